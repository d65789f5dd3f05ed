"""bmr: accurate torque control of bi-directional magneto-rheological actuators, and hysteresis models of any
hysteretic device identified from its measured data.

Core (Rust): ``Hysteresis`` (CBH operator), ``Friction`` (angle-periodic seal friction), ``Compensator``
(exact or paper inverse + friction feedforward, coil split, current limit; ``Compensator.from_model`` adds the
stages of what a diagnosis found, ``ExtendedSimulation`` runs them forwards), ``VirtualActuator`` (a physical
simulator of the rig; ``EFFECTS`` names its switchable effects, ``effect_parameters()`` documents them),
``VirtualDevice`` (a hysteretic device with one input and one output and no angle: ``DEVICE_PRESETS``).
Experiment protocols and bundles of them: ``bmr.experiments`` (:mod:`bmr.simulation.experiments`).
Package layout, in data-flow order: :mod:`bmr.data` (bundles, lab readers) → :mod:`bmr.identification`
(friction, first-order curves, least-squares tables, ``Model``) → :mod:`bmr.diagnosis` → :mod:`bmr.report`;
:mod:`bmr.simulation` drives the virtual actuator; :mod:`bmr.demo` and :mod:`bmr.cli` tie them together.
Identification: ``identify`` (friction + CBH tables from a bundle) giving a ``Model`` (``bmr-model/2`` files)
whose ``identification`` is an ``IdentificationReport``; ``predict`` (runs against a model in the declared units,
calibration explicit, against the single-valued baseline: a ``Prediction``); ``fit_friction``,
``extract_first_order_curves``, ``fit_tables_lstsq`` / ``EverettModel`` (least-squares Preisach tables). Lab data:
``import_logs`` (raw logs of any device, with declared ``Quantities``, into a bundle), ``read_tables`` (instrument
formats), ``read_table``, ``bundle_from_files`` (actuator logs with a column mapping).
Diagnosis: ``diagnose`` (what the model gets wrong, the named cause, the extended model, the held-out gain) giving a
``Diagnosis`` (``bmr-diagnosis/2`` JSON, HTML report); ``diagnose_many`` (many bundles on Dask, one Parquet table).
Units: the actuator's current in A (nominal current spans both coils: negative = coil 1, positive = coil 2),
torque in N·mm, angles in rad, time in s, converter voltages in V; other devices declare theirs (``Quantities``).
Errors: every problem with data is a ``BmrError`` (a ``ValueError``) or one of its kinds (``TableError``,
``BundleError``, ``ModelFileError``, ``ExcitationError``, ``IdentificationError``, ``ResourceLimitError`` for sizes
above the documented ``LIMITS``, ``InUseError`` for an object inside another thread's ``run``); wrong argument
types are ``TypeError``s naming the argument.
"""
from bmr._core import (
    ACTUATOR_PARAMETERS,
    DEVICE_PARAMETERS,
    DEVICE_PRESETS,
    EFFECTS,
    LIMITS,
    PRESETS,
    ActuatorSample,
    BmrError,
    BundleError,
    Command,
    Compensator,
    CompensatorState,
    CurveFit,
    CurveReport,
    EverettFit,
    EverettModel,
    ExcitationError,
    ExtendedSimulation,
    Friction,
    FrictionOrderFit,
    Hysteresis,
    HysteresisState,
    IdentificationError,
    InUseError,
    ModelFileError,
    ResourceLimitError,
    TableError,
    TableReport,
    VirtualActuator,
    VirtualDevice,
    effect_parameters,
    fit_everett,
)
from bmr.data import (
    Bundle,
    Quantities,
    Quantity,
    Run,
    bundle_from_files,
    import_logs,
    read_bundle,
    read_table,
    read_tables,
    write_bundle,
)
from bmr.diagnosis import Diagnosis, diagnose, diagnose_many
from bmr.identification import (
    FrictionFit,
    IdentificationReport,
    Model,
    Prediction,
    extract_first_order_curves,
    fit_friction,
    fit_tables_lstsq,
    identify,
    predict,
)
from bmr.simulation import experiments

__all__ = [
    "ACTUATOR_PARAMETERS",
    "DEVICE_PARAMETERS",
    "DEVICE_PRESETS",
    "EFFECTS",
    "LIMITS",
    "PRESETS",
    "ActuatorSample",
    "BmrError",
    "Bundle",
    "BundleError",
    "Command",
    "Compensator",
    "ExtendedSimulation",
    "CompensatorState",
    "CurveFit",
    "CurveReport",
    "Diagnosis",
    "EverettFit",
    "EverettModel",
    "ExcitationError",
    "Friction",
    "FrictionOrderFit",
    "FrictionFit",
    "Hysteresis",
    "HysteresisState",
    "IdentificationError",
    "IdentificationReport",
    "InUseError",
    "Model",
    "ModelFileError",
    "Prediction",
    "Quantities",
    "Quantity",
    "ResourceLimitError",
    "Run",
    "TableError",
    "TableReport",
    "VirtualActuator",
    "VirtualDevice",
    "bundle_from_files",
    "diagnose",
    "diagnose_many",
    "effect_parameters",
    "experiments",
    "extract_first_order_curves",
    "fit_everett",
    "fit_friction",
    "fit_tables_lstsq",
    "identify",
    "import_logs",
    "predict",
    "read_bundle",
    "read_table",
    "read_tables",
    "write_bundle",
]
__version__ = "0.1.0"
