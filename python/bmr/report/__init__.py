"""Figures and HTML reports: the paper's figures (:mod:`~bmr.report.paper_figures`), the demo report
(:mod:`~bmr.report.demo_report`) and the diagnosis report (:mod:`~bmr.report.diagnosis`)."""
