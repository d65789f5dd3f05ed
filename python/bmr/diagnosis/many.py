"""Many bundles at once: ``bmr.diagnose_many`` and ``bmr diagnose BUNDLE BUNDLE...`` on Dask.

Each bundle is diagnosed by :func:`bmr.diagnose` in a worker process; the results come back as they finish, one
row each, streamed into one Parquet table (``out``) behind a progress bar. A bundle that fails (unreadable
folder, nothing to diagnose, a worker that died) becomes a row with ``status = "error"`` and its message; the
others go on.

Where it runs: a local cluster of worker processes by default (no set-up; ``workers`` of them, one thread each,
the machine's core count by default), a running Dask scheduler with ``scheduler="tcp://host:8786"``, or the
calling process with ``workers=0`` (a plain loop, the same rows). Dask is an optional dependency:
``pip install 'bmr[dask]'``.

What a bundle may be: a bundle folder (read where the diagnosis runs, so a real cluster needs a shared file
system), a :class:`bmr.Bundle` (pickled to the worker), or a zero-argument callable returning one (e.g. a
``functools.partial`` of :func:`bmr.simulation.excitation.diagnosis_bundle`: the bundle is then made on the
worker). ``bundles`` is a sequence (rows named by folder, or ``bundle-<i>``) or a mapping of names to bundles.

Table columns: ``index`` (position in ``bundles``), ``bundle`` (name), ``status`` (``ok`` / ``error``),
``error``, ``device``, ``cause``, ``effects`` (accepted names, comma-separated), ``n_samples``, ``output_unit``,
``noise_floor``, ``nominal_heldout_rms``, ``residual_rms`` (in ``output_unit``), ``cpu_s`` and ``wall_s`` of the
diagnosis, ``worker`` (host:pid) and ``diagnosis`` (the whole ``bmr-diagnosis/2`` JSON).
"""
from __future__ import annotations

import json
import math
import os
import socket
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from bmr._core import BmrError

__all__ = ["diagnose_many", "COLUMNS", "run_cli"]

COLUMNS = ("index", "bundle", "status", "error", "device", "cause", "effects", "n_samples", "output_unit",
           "noise_floor", "nominal_heldout_rms", "residual_rms", "cpu_s", "wall_s", "worker", "diagnosis")
DASK_HINT = "pip install 'bmr[dask]'"


def _schema() -> Any:
    import pyarrow as pa

    types = {"index": pa.int64(), "n_samples": pa.int64(), "noise_floor": pa.float64(),
             "nominal_heldout_rms": pa.float64(), "residual_rms": pa.float64(), "cpu_s": pa.float64(),
             "wall_s": pa.float64()}
    return pa.schema([(c, types.get(c, pa.string())) for c in COLUMNS])


def _named(bundles: Sequence[Any] | Mapping[str, Any]) -> list[tuple[str, Any]]:
    if isinstance(bundles, Mapping):
        return [(str(k), v) for k, v in bundles.items()]
    if isinstance(bundles, (str, Path)):
        bundles = [bundles]
    out = []
    for i, b in enumerate(bundles):
        out.append((str(b) if isinstance(b, (str, Path)) else f"bundle-{i}", b))
    return out


def diagnose_one(index: int, name: str, source: Any, model: Any = None, folds: int = 5, seed: int = 0,
                 closed_loop: bool = False) -> dict[str, Any]:
    """One row of the table: ``source`` (folder, Bundle or callable) diagnosed against ``model`` (None, a model
    file path or a ``bmr-model/1`` dict). Never raises for a bad bundle: the row says what went wrong."""
    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update(index=int(index), bundle=str(name), worker=f"{socket.gethostname()}:{os.getpid()}")
    c0, w0 = time.process_time(), time.perf_counter()
    try:
        from bmr.data.bundle import Bundle, read_bundle
        from bmr.diagnosis.procedure import diagnose
        from bmr.identification.model import Model

        bundle = source() if callable(source) else source
        if isinstance(bundle, (str, Path)):
            bundle = read_bundle(bundle)
        if not isinstance(bundle, Bundle):
            raise BmrError(f"bundle {name!r}: expected a bundle folder, a bmr.Bundle or a callable returning one, "
                           f"got {type(bundle).__name__}")
        m = Model.from_dict(model) if isinstance(model, dict) else model
        d = diagnose(bundle, m, folds=folds, seed=seed, progress=False, closed_loop=closed_loop)
        doc = d.to_dict()
        row.update(status="ok", error="", device=str(d.device), cause=d.cause,
                   effects=",".join(e["name"] for e in d.effects),
                   n_samples=int(sum(len(r.data) for r in bundle.runs)), output_unit=d.quantities.output.unit,
                   noise_floor=d.noise_floor, nominal_heldout_rms=d.nominal_heldout_rms, residual_rms=d.residual_rms,
                   diagnosis=json.dumps(doc, allow_nan=False))
    except Exception as exc:  # a failed bundle is a row, never the end of the batch
        msg = str(exc) if isinstance(exc, BmrError) else "".join(
            traceback.format_exception_only(type(exc), exc)).strip()
        row.update(status="error", error=msg)
    row.update(cpu_s=time.process_time() - c0, wall_s=time.perf_counter() - w0)
    return row


def _error_row(index: int, name: str, message: str) -> dict[str, Any]:
    row: dict[str, Any] = {c: None for c in COLUMNS}
    row.update(index=int(index), bundle=str(name), status="error", error=message)
    return row


class _ParquetStream:
    """Rows appended to a Parquet file as they arrive (one row group each), written to a temporary file in the
    destination folder and renamed over ``path`` when closed: a reader never sees a half-written table."""

    def __init__(self, path: str | Path | None) -> None:
        self.path = Path(path) if path is not None else None
        self._writer = None
        self._tmp: str | None = None
        if self.path is not None:
            import pyarrow.parquet as pq

            folder = self.path.parent
            if not folder.is_dir():
                raise BmrError(f"cannot write {str(self.path)!r}: folder {str(folder)!r} does not exist")
            fd, self._tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", suffix=".tmp", dir=folder)
            os.close(fd)
            self._writer = pq.ParquetWriter(self._tmp, _schema())

    def write(self, row: dict[str, Any]) -> None:
        if self._writer is not None:
            import pyarrow as pa

            clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
            self._writer.write_table(pa.Table.from_pylist([clean], schema=_schema()))

    def close(self, ok: bool = True) -> None:
        if self._writer is None or self._tmp is None or self.path is None:
            return
        self._writer.close()
        self._writer = None
        if ok:
            with open(self._tmp, "rb") as fh:
                os.fsync(fh.fileno())
            os.replace(self._tmp, self.path)
        else:
            Path(self._tmp).unlink(missing_ok=True)


def _results_dask(jobs: list[tuple[int, str, Any]], kwargs: dict[str, Any], scheduler: str | None,
                  workers: int | None) -> Iterator[dict[str, Any]]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise BmrError(f"diagnosing many bundles runs on Dask, which is not installed: {DASK_HINT}") from None
    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError) as exc:
            raise BmrError(f"cannot reach the Dask scheduler {scheduler!r}: {exc}") from None
    else:
        n = workers if workers is not None else (os.cpu_count() or 1)
        cluster = LocalCluster(n_workers=max(1, int(n)), threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    try:
        futures, job_of = [], {}
        for index, name, source in jobs:
            fut = client.submit(diagnose_one, index, name, source, pure=False, **kwargs)
            job_of[fut.key] = (index, name)
            futures.append(fut)
        for fut in as_completed(futures):
            index, name = job_of[fut.key]
            try:
                yield fut.result()
            except Exception as exc:  # the worker died or the task could not run at all
                yield _error_row(index, name, f"{type(exc).__name__}: {exc}")
            fut.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def diagnose_many(bundles: Sequence[Any] | Mapping[str, Any], out: str | Path | None = None, *, model: Any = None,
                  folds: int = 5, seed: int = 0, closed_loop: bool = False, scheduler: str | None = None,
                  workers: int | None = None, progress: bool = True) -> Any:
    """Diagnose every bundle (see the module doc) and return the table as a ``pandas.DataFrame`` in the order
    of ``bundles``; ``out``: also stream the rows into this Parquet file as they finish. ``model``: a
    ``bmr.Model``, a model file or None (identify each bundle's own). ``scheduler``: address of a running Dask
    scheduler (default: a local cluster of ``workers`` processes; ``workers=0``: no Dask, one process)."""
    import pandas as pd
    from tqdm import tqdm

    jobs = [(i, name, src) for i, (name, src) in enumerate(_named(bundles))]
    if not jobs:
        raise BmrError("diagnose_many needs at least one bundle")
    if model is not None and not isinstance(model, (str, Path, dict)):
        to_dict: Callable[[], dict] | None = getattr(model, "to_dict", None)
        if to_dict is None:
            raise BmrError(f"model must be a bmr.Model, a model file or None, got {type(model).__name__}")
        model = to_dict()
    elif isinstance(model, Path):
        model = str(model)
    kwargs = {"model": model, "folds": folds, "seed": seed, "closed_loop": closed_loop}
    stream = _ParquetStream(out)
    rows: list[dict[str, Any]] = []
    ok = False
    bar = tqdm(total=len(jobs), file=sys.stderr, desc="bmr diagnose", unit="bundle", disable=not progress)
    try:
        if workers == 0 and not scheduler:
            results: Iterator[dict[str, Any]] = (diagnose_one(i, n, s, **kwargs) for i, n, s in jobs)
        else:
            results = _results_dask(jobs, kwargs, scheduler, workers)
        for row in results:
            rows.append(row)
            stream.write(row)
            bar.set_postfix_str(f"{row['bundle']}: {row['cause'] if row['status'] == 'ok' else 'error'}")
            bar.update(1)
        ok = True
    finally:
        bar.close()
        stream.close(ok)
    return pd.DataFrame(sorted(rows, key=lambda r: r["index"]), columns=list(COLUMNS))


def run_cli(args: Any) -> int:
    """``bmr diagnose BUNDLE BUNDLE... [--out TABLE.parquet] [--scheduler tcp://…] [--workers N]``: one line per
    bundle, the table in Parquet; exit code 1 when any bundle failed."""
    out = args.out or "bmr-diagnoses.parquet"
    table = diagnose_many(args.bundle, out, model=args.model, folds=args.folds, seed=args.seed,
                          scheduler=args.scheduler, workers=args.workers)
    failed = 0
    for r in table.itertuples():
        if r.status == "ok":
            print(f"{r.bundle}: cause {r.cause}; effects {r.effects or '-'}; held-out RMS "
                  f"{r.nominal_heldout_rms:.4g} -> {r.residual_rms:.4g} {r.output_unit} (noise {r.noise_floor:.4g}); "
                  f"{r.cpu_s:.1f} CPU-s")
        else:
            failed += 1
            print(f"{r.bundle}: error: {r.error}")
    print(f"bmr diagnose: {len(table)} bundles, {len(table) - failed} diagnosed, {failed} failed; table in {out}")
    return 1 if failed else 0
