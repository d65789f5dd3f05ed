"""Call every binding of ``bmr._core`` with hostile sizes and values, one argument at a time.

Run as a script (in a child process, so that an abort cannot take the test session down): prints one JSON line per
call whose outcome is not allowed, then ``DONE <calls>``. Allowed outcomes: a return value, a ``bmr.BmrError`` (or
subclass), a ``TypeError`` that names the argument, an ``OverflowError`` for integers beyond 64 bits. Not allowed:
a Rust panic (``PanicException``), any other exception or warning (a silent conversion), an abort.
"""
from __future__ import annotations

import inspect
import json
import pickle
import sys
import warnings

import numpy as np

import bmr._core as core

HOSTILE = [
    None, True, -1, 0, 1, 2**31 - 1, 2**62, 2**63, 2**64, 10**12, 10**30,
    float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 5e-324, -0.0,
    "", "nope", b"\x00" * 16, [], [[]], [1.0, "x"], {}, {"a": 1}, (1, 2), object(),
    np.array([]), np.full(5, np.nan), np.array([1e308, -1e308, 1e308]), np.zeros((3, 3)),
    np.array([1 + 2j, 3.0]), np.array([True, False, True]), np.arange(5000, dtype=float) * 1e300,
]


def _family(sign: float, n: int = 4) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for k in range(n):
        r = -1.0 + 2.0 * k / n
        if sign > 0:
            u = np.linspace(r, 1.0, 9)
        else:
            u = np.linspace(-r, -1.0, 9)
        out.append((u, 100.0 * (u + 1.0)))
    return out


def _hysteresis() -> core.Hysteresis:
    return core.Hysteresis.from_curves(_family(1.0), _family(-1.0))


def _everett() -> core.EverettModel:
    return core.EverettModel(np.linspace(-1, 1, 9), np.full(36, 0.1), 0.0)


U = np.sin(np.linspace(0, 20, 300))
TH = np.linspace(0, 30, 300)
SANE: dict[str, object] = {
    "ascending": _family(1.0), "descending": _family(-1.0), "initial": None, "monotone_tolerance": 0.005,
    "reach_tolerance": 0.01, "closure_tolerance": 0.05, "max_nodes": 1024, "node_tolerance": 0.0, "history": None,
    "u": U, "theta_rad": TH,
    "torque_nmm": np.sin(TH), "order": 2, "grid": np.linspace(-1, 1, 9),
    "runs": [(U, 10 * U, np.ones_like(U), 0)], "n_offsets": 1, "smoothing": 1e-4, "diagonal_smoothing": 0.5,
    "ridge": 1e-9, "max_iter": 500,
    "masses": np.full(36, 0.1), "offset": 0.0, "beta": -0.5, "alpha": 0.5, "subdivisions": 2, "current_a": U,
    "n": 10, "preset": "bmr2013", "seed": 0, "sample_rate_hz": 1000.0, "effects": None, "overrides": None,
    "friction": None, "inverse": "exact", "converter_gain": 0.125, "current_limit": 1.25,
    "torque_ref_nmm": 100 * U, "c0": 1.0, "a": [0.5], "b": [0.2], "amplitude": [1.0], "phase": [0.3],
    "inputs": [(U, np.ones_like(U), 0)], "outputs": [10 * U], "warm_start": None, "deadband": 0.05, "lo": -1.0,
    "hi": 1.0, "saturation_tol": None, "y": 10 * U, "weight": None, "free_offset": True, "gain": 1.0,
    "tolerance": 1e-3, "direction": "ascending", "pilot": 16, "gain_per_a": 0.0, "extensions": None,
    "dt_s": 1e-3, "full_torque_nmm": None, "full_current_a": 1.25, "columns": None, "out": None, "heating": 0.0,
    "t0_s": 0.0, "x": U, "delay_s": 3e-3, "fill": None, "tau_s": 0.01, "model_entries": False, "language": "c",
    "title": "bmr compensator", "prefix": "bmr", "core_nmm": 100 * U, "field_nmm": 100 * U, "curvature": 0.2,
    "scale_nmm": 300.0, "torque_ref_ahead_nmm": 50.0, "theta_ahead_rad": 0.3, "slope_ref": None, "rest_s": 0.0,
    "kappa": 0.1, "cycles": 5.0, "deadband": 0.05, "y_mid": 0.0, "t_s": np.arange(300) / 1000.0, "harmonics": 0,
    "v": 10 * U, "taus_s": np.array([0.01, 0.1]), "signed": False, "cubic": 0.3,
}
SANE["subdivisions"] = 2
SANE["drift"] = [np.cumsum(U) * 1e-3]  # one running input integral per run (the leakage column)
# Per-callable values where the generic ones do not fit (scalars for single steps, objects for methods).
SPECIFIC: dict[str, dict[str, object]] = {
    "VirtualActuator.step": {"current_a": 0.3},
    "Compensator.step": {"torque_ref_nmm": 50.0, "theta_rad": 0.3},
    "EverettModel.simulate": {"offset": None},
    "VirtualActuator.true_friction": {"theta_rad": TH},
}


def _model() -> object:
    import bmr

    return bmr.Model.from_curves(_family(1.0), _family(-1.0))


def _reduce_args(obj: object) -> tuple:
    return obj.__reduce__()[1]


def _targets() -> list[tuple[str, object, dict[str, object]]]:
    """(name, callable, sane arguments) for every function and method."""
    h = _hysteresis()
    h.run(U)
    va = core.VirtualActuator()
    comp = core.Compensator(_hysteresis(), core.Friction(1.0, [0.5], [0.2]))
    asc, an, ac, desc, dn, dc, ylo, yhi, state = _reduce_args(h)
    vargs = _reduce_args(va)
    paper = core.Compensator(_hysteresis(), core.Friction(1.0, [0.5], [0.2]), inverse="paper")
    paper.run(100 * U, TH)
    comp_args = dict(zip(("hysteresis", "friction", "inverse", "converter_gain", "current_limit", "extensions",
                          "dt_s", "full_torque_nmm", "state"), _reduce_args(paper)))
    (comp_state,) = _reduce_args(paper.snapshot())
    command = _reduce_args(comp.step(50.0, 0.3))
    ctl = core.Controller(comp, dt_s=1e-3)
    ctl.step(50.0, 0.3, 48.0)
    ctl_args = dict(zip(("compensator", "dt_s", "settings", "state"), _reduce_args(ctl)))
    targets: list[tuple[str, object, dict[str, object]]] = [
        ("Hysteresis.from_curves", core.Hysteresis.from_curves, {}),
        ("Hysteresis.step", _hysteresis().step, {"u": 0.3}),
        ("Hysteresis.run", _hysteresis().run, {}),
        ("Hysteresis.reset", _hysteresis().reset, {}),
        ("Hysteresis.compressed", _hysteresis().compressed, {}),
        ("Hysteresis.run_rate_dependent", _hysteresis().run_rate_dependent, {"tau_s": 0.01}),
        ("Hysteresis.run_mean_field", _hysteresis().run_mean_field, {"per_output": 1e-3}),
        ("VirtualActuator.start_run", core.VirtualActuator().start_run, {}),
        ("VirtualDevice", core.VirtualDevice, {"preset": "piezo", "sample_rate_hz": None}),
        ("VirtualDevice.run", core.VirtualDevice().run, {"u": 50 * U}),
        ("VirtualDevice.start_run", core.VirtualDevice().start_run, {}),
        ("accommodation_shift", core.accommodation_shift, {"saturation_tol": 0.002}),
        ("candidate_signals", core.candidate_signals, {"theta_rad": None}),
        ("creep_relaxation", core.creep_relaxation, {}),
        ("creep_fluctuation_shift", core.creep_fluctuation_shift, {"tau0_s": 0.05}),
        ("fit_curve", core.fit_curve, {"u": np.linspace(0, 1, 200), "y": np.linspace(0, 1, 200) ** 2}),
        ("Hysteresis.restore", _hysteresis().restore, {"state": _hysteresis().snapshot()}),
        ("fit_friction_order", core.fit_friction_order, {}),
        ("fit_everett", core.fit_everett, {}),
        ("EverettRegression", core.EverettRegression, {}),
        ("EverettRegression.fit", core.EverettRegression(np.linspace(-1, 1, 9), [(U, np.ones_like(U), 0)]).fit, {}),
        ("EverettFolds", core.EverettFolds, {"runs": [(U, 10 * U, np.ones_like(U), np.arange(U.size) % 3, 0, [], 1.0)],
                                              "folds": 3}),
        ("EverettFolds.score", core.EverettFolds(np.linspace(-1, 1, 9), [(U, U, np.ones_like(U), np.arange(U.size) % 3,
                                                                         0, [], 1.0)]).score, {}),
        ("find_reversals", core.find_reversals, {}),
        ("reversal_order", core.reversal_order, {"deadband": 0.05}),
        ("EverettModel", core.EverettModel, {}),
        ("EverettModel.everett", _everett().everett, {}),
        ("EverettModel.simulate", _everett().simulate, {}),
        ("EverettModel.best_initial_state", _everett().best_initial_state, {}),
        ("EverettModel.first_order_curves", _everett().first_order_curves, {}),
        ("EverettModel.hysteresis", _everett().hysteresis, {}),
        ("VirtualActuator", core.VirtualActuator, {}),
        ("VirtualActuator.run", va.run, {}),
        ("VirtualActuator.step", va.step, {}),
        ("VirtualActuator.theta_ahead", va.theta_ahead, {}),
        ("VirtualActuator.true_friction", va.true_friction, {}),
        ("Friction", core.Friction, {}),
        ("Friction.__call__", lambda theta: core.Friction(1.0, [0.5], [0.2])(theta), {"theta": TH}),
        ("Friction.from_amplitude_phase", core.Friction.from_amplitude_phase, {}),
        ("Compensator", core.Compensator, {"hysteresis": _hysteresis()}),
        ("Compensator.step", comp.step, {}),
        ("Compensator.step_ahead", comp.step_ahead, {}),
        ("Compensator.step_into", comp.step_into, {"torque_ref_nmm": 50.0, "theta_rad": 0.3, "out": np.zeros(7)}),
        ("Compensator.from_model", core.Compensator.from_model, {"model": _model()}),
        ("ExtendedSimulation", core.ExtendedSimulation, {"hysteresis": _hysteresis()}),
        ("ExtendedSimulation.run", core.ExtendedSimulation(_hysteresis(), dt_s=1e-3, full_current_a=1.25).run, {}),
        ("check_extensions", core.check_extensions, {"extensions": [{"name": "coil_lag", "params": {"tau_s": 0.01}}]}),
        ("delay", core.delay, {}),
        ("drift_offset", core.drift_offset, {"t_s": U, "settle_per_s": 0.1}),
        ("effect_parameters", core.effect_parameters, {}),
        ("export_source", core.export_source, {"compensator": comp}),
        ("friction_series", core.friction_series, {}),
        ("heating_state", core.heating_state, {"current_a": U, "tau_s": 0.1, "initial": 0.0}),
        ("lag", core.lag, {}),
        ("leak_integral", core.leak_integral, {"x": U, "dt_s": 1e-3, "decay_per_s": 0.1}),
        ("lead", core.lead, {}),
        ("output_map", core.output_map, {}),
        ("output_map_inverse", core.output_map_inverse, {}),
        ("Compensator.run", comp.run, {}),
        ("Compensator.reset", comp.reset, {}),
        ("Compensator.restore", comp.restore, {"state": comp.snapshot()}),
        ("_rebuild_hysteresis", core._rebuild_hysteresis,
         dict(asc=asc, asc_nodes=an, asc_curves=ac, desc=desc, desc_nodes=dn, desc_curves=dc, y_lo=ylo, y_hi=yhi,
              state=state)),
        ("_rebuild_hysteresis_state", core._rebuild_hysteresis_state, {"state": state}),
        ("_rebuild_compensator", core._rebuild_compensator, comp_args),
        ("_rebuild_compensator_state", core._rebuild_compensator_state, {"state": comp_state}),
        ("Command", core.Command,
         dict(zip(("current_a", "coil1_a", "coil2_a", "volt1_v", "volt2_v", "saturated", "fault"), command))),
        ("Controller", core.Controller,
         {"compensator": comp, "dt_s": 1e-3, "bandwidth_hz": 0.0, "noise_share": 0.02, "adaptation_time_s": 5.0,
          "fault_after": 50, "correction_limit_nmm": 0.0, "feedback": True, "adaptation": True}),
        ("Controller.from_model", core.Controller.from_model, {"model": _model(), "dt_s": 1e-3}),
        ("Controller.step", ctl.step, {"reference_nmm": 50.0, "theta_rad": 0.3, "measured_nmm": 48.0}),
        ("Controller.freeze_adaptation", ctl.freeze_adaptation, {"frozen": True}),
        ("Controller.reset", ctl.reset, {}),
        ("Controller.restore", ctl.restore, {"state": ctl.snapshot()}),
        ("_rebuild_controller", core._rebuild_controller, ctl_args),
        ("_simulate_closed_loop", core._simulate_closed_loop,
         {"controller": core.Controller(comp, dt_s=1e-3), "plant": core.VirtualActuator(), "reference_nmm": 50 * U,
          "theta_rad": None}),
        ("_rebuild_virtual_actuator", core._rebuild_virtual_actuator,
         dict(zip(("preset", "seed", "sample_rate_hz", "effects", "overrides", "state"), vargs))),
    ]
    return targets


def _params(fn: object) -> list[inspect.Parameter]:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return []
    return [p for p in sig.parameters.values()
            if p.name not in ("self", "$self") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _call(fn: object, params: list[inspect.Parameter], values: dict[str, object]) -> None:
    args, kwargs = [], {}
    for p in params:
        if p.kind == p.KEYWORD_ONLY:
            kwargs[p.name] = values[p.name]
        else:
            args.append(values[p.name])
    fn(*args, **kwargs)


def _bindings_with_arguments() -> set[str]:
    """Every function and method of the module that takes arguments (so a new binding cannot escape the sweep)."""
    names = set()
    for attr in dir(core):
        obj = getattr(core, attr)
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            if _params(obj):
                names.add(attr)
            for m in dir(obj):
                if not m.startswith("_") and callable(getattr(obj, m)) and _params(getattr(obj, m)):
                    names.add(f"{attr}.{m}")
        elif callable(obj) and not inspect.isclass(obj) and _params(obj):
            names.add(attr)
    return names


def main() -> int:
    # A silent conversion (complex to real, say) is a finding too.
    warnings.simplefilter("error")
    allowed = (core.BmrError, OverflowError)
    calls = 0
    targets = _targets()
    for name in sorted(_bindings_with_arguments() - {t[0] for t in targets}):
        print(json.dumps({"call": name, "problem": "binding not in the sweep: add it to _targets()"}), flush=True)
    for name, fn, specific in targets:
        params = _params(fn)
        base = {p.name: SANE[p.name] for p in params if p.name in SANE}
        base.update(SPECIFIC.get(name, {}))
        base.update(specific)
        missing = [p.name for p in params if p.name not in base]
        if missing:
            print(json.dumps({"call": name, "problem": f"no sane value for {missing}"}), flush=True)
            continue
        _call(fn, params, base)  # the sane call itself must work
        for p in params:
            for value in HOSTILE:
                values = dict(base)
                values[p.name] = value
                calls += 1
                try:
                    _call(fn, params, values)
                except allowed:
                    pass
                except TypeError as exc:
                    # The argument's name is in the message or in a note ("while processing 'n'").
                    if p.name not in str(exc) + " ".join(getattr(exc, "__notes__", [])):
                        print(json.dumps({"call": name, "arg": p.name, "value": repr(value)[:60],
                                          "problem": f"TypeError not naming the argument: {exc}"}), flush=True)
                except BaseException as exc:  # noqa: BLE001 - PanicException is a BaseException
                    print(json.dumps({"call": name, "arg": p.name, "value": repr(value)[:60],
                                      "problem": f"{type(exc).__name__}: {exc}"[:300]}), flush=True)
    # Pickled data is data too: damaged pickles of every picklable object give errors, never panics.
    paper = core.Compensator(_hysteresis(), core.Friction(1.0, [0.5], [0.2]), inverse="paper")
    paper.run(100 * U, TH)
    for obj in (_hysteresis(), _hysteresis().snapshot(), core.VirtualActuator(), _everett(), paper,
                paper.snapshot(), core.Friction(1.0, [0.5], [0.2]), paper.step(10.0, 0.2)):
        blob = pickle.dumps(obj)
        for i in range(0, len(blob), max(1, len(blob) // 200)):
            for b in (0, 0xFF, 0x7F):
                calls += 1
                damaged = blob[:i] + bytes([b]) + blob[i + 1:]
                try:
                    pickle.loads(damaged)
                except Exception:  # noqa: BLE001 - any ordinary error is fine; a panic is not
                    pass
                except BaseException as exc:  # noqa: BLE001
                    print(json.dumps({"call": f"pickle.loads({type(obj).__name__})", "arg": str(i),
                                      "problem": f"{type(exc).__name__}: {exc}"[:300]}), flush=True)
    print(f"DONE {calls}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
