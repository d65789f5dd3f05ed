"""Every binding under hostile sizes and values, documented limits, copy/pickle, and objects in use by another
thread."""
from __future__ import annotations

import copy
import pickle
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import bmr._core as core

HERE = Path(__file__).resolve().parent


def _family(sign: float, n: int, samples: int = 5) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for k in range(n):
        r = -1.0 + 2.0 * k / n
        u = np.linspace(r, 1.0, samples) if sign > 0 else np.linspace(-r, -1.0, samples)
        out.append((u, 100.0 * (u + 1.0)))
    return out


def _hysteresis() -> core.Hysteresis:
    return core.Hysteresis.from_curves(_family(1.0, 6), _family(-1.0, 6))


def test_every_binding_survives_hostile_sizes_and_values() -> None:
    # In a child process: an abort (allocation failure) must show up as a failure, not end the session.
    proc = subprocess.run([sys.executable, str(HERE / "hostile_bindings.py")], capture_output=True, text=True,
                          timeout=900)
    problems = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    assert proc.returncode == 0, f"child died with {proc.returncode}: {proc.stderr[-2000:]}"
    assert proc.stdout.splitlines()[-1].startswith("DONE "), proc.stdout[-2000:]
    assert not problems, "\n".join(problems[:40])


@pytest.mark.parametrize("curves", [100_001, 10_000])
def test_curve_counts_are_bounded_before_anything_is_allocated(curves: int) -> None:
    # 100 001 curves asked for 80 GB and aborted the interpreter; 10 000 took 14 s.
    small = [(np.array([0.0, 1.0]), np.array([0.0, 1.0]))] * curves
    with pytest.raises(core.ResourceLimitError, match="number of curves is"):
        core.Hysteresis.from_curves(small, small)
    assert issubclass(core.ResourceLimitError, core.BmrError)


@pytest.mark.parametrize(("call", "match"), [
    (lambda: core.VirtualActuator().theta_ahead(10**12), "angle samples"),
    (lambda: core.VirtualActuator().theta_ahead(2**62), "angle samples"),
    (lambda: core.fit_friction_order(np.linspace(0, 9, 50), np.zeros(50), 2**63), "harmonic order"),
    (lambda: core.fit_everett(np.linspace(-1, 1, 9), [(np.zeros(5), np.zeros(5), np.ones(5), 0)], n_offsets=10**6),
     "unknowns"),
    (lambda: core.fit_everett(np.linspace(-1, 1, 10**6), [(np.zeros(5), np.zeros(5), np.ones(5), 0)]),
     "grid intervals"),
    (lambda: core.EverettModel(np.linspace(-1, 1, 9), np.full(36, 0.1), 0.0).first_order_curves(10**9), "points"),
    (lambda: core.Hysteresis.from_curves(_family(1.0, 3), _family(-1.0, 3), max_nodes=10**9), "max_nodes"),
], ids=["theta_ahead_1e12", "theta_ahead_2e62", "friction_order", "everett_offsets", "everett_grid",
        "first_order_curves", "max_nodes"])
def test_user_sizes_raise_resource_limit_errors(call, match: str) -> None:
    with pytest.raises(core.ResourceLimitError, match=match):
        call()


def test_limits_are_documented_in_the_module() -> None:
    assert core.LIMITS["curves_per_family"] == 4096
    assert set(core.LIMITS) >= {"max_nodes", "table_values_per_family", "magnitude", "generated_samples",
                                "friction_fit_order", "everett_intervals", "everett_unknowns",
                                "everett_large_unknowns", "everett_entries"}


def test_table_errors_have_their_own_class_and_speak_the_users_terms() -> None:
    # Was "reversal is not a grid node (at index 1)", an internal term with the index after sorting.
    asc, desc = _family(1.0, 4), _family(-1.0, 4)
    asc.insert(1, (asc[1][0] + 1e-13, asc[1][1]))
    with pytest.raises(core.TableError, match=r"ascending curves 1 and 2 start at reversal inputs"):
        core.Hysteresis.from_curves(asc, desc)


@pytest.mark.parametrize("scale", [4e154, 1e308])
def test_inputs_beyond_the_supported_magnitude_are_a_range_error(scale: float) -> None:
    # 4e154 was accepted and then returned inf; 1e308 gave the internal "fewer than 2 grid nodes".
    big = [(u * scale, y) for u, y in _family(1.0, 4)], [(u * scale, y) for u, y in _family(-1.0, 4)]
    with pytest.raises(core.TableError, match="supported magnitude"):
        core.Hysteresis.from_curves(*big)
    assert core.LIMITS["magnitude"] == 1e150


FRICTION = core.Friction(3.0, [2.0, -1.0], [0.5, 0.25])
REF = 180.0 * np.sin(np.linspace(0, 17, 500))
ANGLE = np.linspace(0.0, 40.0, 500)


def _compensator(inverse: str) -> core.Compensator:
    c = core.Compensator(_hysteresis(), FRICTION, inverse=inverse, converter_gain=0.25, current_limit=0.9)
    c.run(REF, ANGLE)
    return c


def _sample_objects() -> dict[str, object]:
    h = _hysteresis()
    h.run(np.sin(np.linspace(0, 20, 400)))
    va = core.VirtualActuator(effects=["coil_lag:tau_s=0.01", "time_delay:delay_s=0.003"],
                              overrides={"sensor.noise_n": 0.2}, seed=4)
    va.run(np.linspace(-1, 1, 200))
    return {
        "Hysteresis": h,
        "HysteresisState": h.snapshot(),
        "VirtualActuator": va,
        "EverettModel": core.EverettModel(np.linspace(-1, 1, 9), np.linspace(0.0, 0.2, 36), -3.0),
        "Compensator": _compensator("exact"),
        "PaperCompensator": _compensator("paper"),
        "CompensatorState": _compensator("paper").snapshot(),
        "Friction": FRICTION,
        "Command": _compensator("exact").step(-40.0, 1.0),
    }


def _continue(obj: object) -> object:
    """What an object does next, for comparing a copy with its original."""
    u = np.sin(np.linspace(0, 13, 600)) * 0.9
    if isinstance(obj, core.Hysteresis):
        return obj.run(u)
    if isinstance(obj, core.HysteresisState):
        h = _hysteresis()
        h.run(np.sin(np.linspace(0, 20, 400)))  # same tables; restore then continue
        h.restore(obj)
        return h.run(u)
    if isinstance(obj, core.VirtualActuator):
        return obj.run(u)
    if isinstance(obj, core.EverettModel):
        return obj.simulate(u)
    if isinstance(obj, core.Compensator):
        return {**obj.run(200 * u, 7 * u), "settings": np.array([obj.converter_gain, obj.current_limit]),
                "inverse": np.array([obj.inverse])}
    if isinstance(obj, core.CompensatorState):
        c = _compensator("paper")  # same tables and inverse; restore then continue
        c.run(-REF, ANGLE)
        c.restore(obj)
        return c.run(200 * u, 7 * u)
    if isinstance(obj, core.Friction):
        return obj(np.linspace(-7, 7, 99))
    if isinstance(obj, core.Command):
        return np.array([obj.current_a, obj.coil1_a, obj.coil2_a, obj.volt1_v, obj.volt2_v, obj.saturated,
                         obj.fault])
    raise AssertionError(type(obj))


def _equal(a: object, b: object) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    return np.array_equal(a, b)


@pytest.mark.parametrize("how", ["copy", "deepcopy", "pickle"])
@pytest.mark.parametrize("name", ["Hysteresis", "HysteresisState", "VirtualActuator", "EverettModel", "Compensator",
                                  "PaperCompensator", "CompensatorState", "Friction", "Command"])
def test_objects_copy_and_pickle_and_continue_bit_for_bit(name: str, how: str) -> None:
    # Compensators, friction, their states and commands could not be copied or pickled (users send compensators
    # to worker processes).
    original = _sample_objects()[name]
    twin = {"copy": copy.copy, "deepcopy": copy.deepcopy,
            "pickle": lambda o: pickle.loads(pickle.dumps(o))}[how](original)
    assert type(twin) is type(original)
    assert _equal(_continue(twin), _continue(original))


def test_a_pickled_state_restores_only_into_its_own_tables() -> None:
    s = pickle.loads(pickle.dumps(_hysteresis().snapshot()))
    other = core.Hysteresis.from_curves(_family(1.0, 5), _family(-1.0, 5))
    with pytest.raises(core.TableError, match="does not belong"):
        other.restore(s)
    with pytest.raises(core.BmrError):
        core._rebuild_hysteresis_state(b"\x00" * 24)


def test_a_pickled_compensator_state_restores_only_into_a_compensator_like_its_own() -> None:
    paper = pickle.loads(pickle.dumps(_compensator("paper").snapshot()))
    exact = pickle.loads(pickle.dumps(_compensator("exact").snapshot()))
    with pytest.raises(core.TableError, match="does not belong"):
        _compensator("exact").restore(paper)
    with pytest.raises(core.TableError, match="does not belong"):
        _compensator("paper").restore(exact)
    other = core.Compensator(core.Hysteresis.from_curves(_family(1.0, 5), _family(-1.0, 5)), inverse="paper")
    with pytest.raises(core.TableError, match="does not belong"):
        other.restore(paper)
    # Damaged state bytes are refused when unpickled or, at the latest, when restored.
    with pytest.raises(core.BmrError):
        _compensator("paper").restore(core._rebuild_compensator_state(b"\x00" * 56))


def _race(run_long, call_other) -> list[BaseException]:
    """Call `call_other` repeatedly while `run_long` runs in another thread; returns the exceptions seen."""
    seen: list[BaseException] = []
    started = threading.Event()

    def worker() -> None:
        started.set()
        run_long()

    t = threading.Thread(target=worker)
    t.start()
    started.wait()
    while t.is_alive():
        try:
            call_other()
        except BaseException as exc:  # noqa: BLE001 - recorded and checked below
            seen.append(exc)
    t.join()
    return seen


@pytest.mark.parametrize("name", ["Hysteresis", "VirtualActuator", "Compensator"])
def test_a_call_during_a_gil_released_run_says_the_object_is_in_use(name: str) -> None:
    # Used to be "RuntimeError: Already borrowed".
    if name == "Hysteresis":
        obj = _hysteresis()
        u = np.sin(np.linspace(0, 2000, 4_000_000))
        run_long, call_other = (lambda: obj.run(u)), (lambda: obj.step(0.1))
    elif name == "Compensator":
        obj = core.Compensator(_hysteresis(), FRICTION)
        u = np.sin(np.linspace(0, 2000, 2_000_000))
        run_long, call_other = (lambda: obj.run(150 * u, u)), (lambda: obj.step(10.0, 0.1))
    else:
        obj = core.VirtualActuator()
        u = np.sin(np.linspace(0, 200, 300_000))
        run_long, call_other = (lambda: obj.run(u)), (lambda: obj.step(0.1))
    for _ in range(5):
        seen = _race(run_long, call_other)
        if seen:
            break
    assert seen, "the other thread never met the running call"
    assert all(isinstance(e, core.InUseError) for e in seen), {type(e).__name__ for e in seen}
    assert "in use by another thread" in str(seen[0])
    assert issubclass(core.InUseError, core.BmrError)


def test_the_configuration_of_a_running_actuator_can_still_be_read() -> None:
    va = core.VirtualActuator()
    u = np.zeros(300_000)
    seen = _race(lambda: va.run(u), lambda: (va.sample_rate_hz, va.effects, va.parameters, va.seed))
    assert not seen, seen[:3]
