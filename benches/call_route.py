"""The route a bundle takes through bmr's Python modules in ``identify`` and ``diagnose``: which modules are
visited, how often the flow comes back to a module it already left, and how often a run's arrays are built from
its table (``Run.column`` copying a pandas column into a new numpy array, per run and signal, instead of returning a view).

    python benches/call_route.py [--bundle DIR] [--what identify,diagnose]

Without ``--bundle`` the quick diagnosis bundle (``rig_preisach`` + ``coil_lag``, seed 0) is made first. Counts
are of Python calls (``sys.setprofile``), so they measure the structure of the code, not its speed.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from typing import Any, Callable

import bmr
from bmr.simulation.excitation import diagnosis_bundle


class Route:
    """Module transitions of the Python calls inside the ``bmr`` package."""

    def __init__(self) -> None:
        self.visited: list[str] = []
        self.returns = 0
        self.back_edges: set[tuple[str, str]] = set()
        self.current: str | None = None
        self.columns: Counter[tuple[str, str]] = Counter()

    def __call__(self, frame: Any, event: str, arg: Any) -> None:
        module = frame.f_globals.get("__name__", "")
        if event == "return" and frame.f_code.co_name == "column" and module == "bmr.data.bundle":
            # An array that owns its samples was built (copied) from the table; a view was not.
            if getattr(arg, "base", 0) is None:
                run = frame.f_locals.get("self")
                self.columns[(getattr(run, "name", "?"), str(frame.f_locals.get("name")))] += 1
            return
        if event != "call" or not module.startswith("bmr"):
            return
        if module != self.current:
            if module in self.visited:
                self.returns += 1
                self.back_edges.add((self.current or "", module))
            else:
                self.visited.append(module)
            self.current = module


def trace(fn: Callable[[], Any]) -> Route:
    route = Route()
    sys.setprofile(route)
    try:
        fn()
    finally:
        sys.setprofile(None)
    return route


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bundle", help="a bundle folder (default: the quick diagnosis bundle)")
    ap.add_argument("--what", default="identify,diagnose")
    args = ap.parse_args(argv)
    bundle = (bmr.read_bundle(args.bundle) if args.bundle else
              diagnosis_bundle("rig_preisach", effects={"coil_lag": {"tau_s": 0.02}}, seed=0))
    jobs = {"identify": lambda: bmr.identify(bundle),
            "diagnose": lambda: bmr.diagnose(bundle, progress=False, closed_loop=False)}
    print(f"{bundle!r}")
    print("| call | modules visited | calls returning to a module already visited (distinct module pairs) "
          "| run arrays built from the table | most per run and signal |")
    print("|---|---|---|---|---|")
    for name in args.what.split(","):
        r = trace(jobs[name])
        most = max(r.columns.values(), default=0)
        print(f"| `bmr.{name}` | {len(r.visited)} | {r.returns} ({len(r.back_edges)}) | {sum(r.columns.values())} "
              f"| {most} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
