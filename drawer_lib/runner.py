"""The stage runner every DVC stage uses.

``with stage_run("capture", out_dir, seed=cfg.seed) as run:`` gives a fresh temporary directory
``run.dir`` to write into, a seeded ``run.rng``, progress bars, a ``curve.csv`` helper and a
``metrics`` dict. On success it adds ``wall_s``, ``peak_rss_mb`` and ``threads``, refuses non-finite metrics,
writes ``metrics.json`` and swaps the temporary directory into place in one rename; on any error
the temporary directory is removed and the previous output is left untouched, so an interrupted
stage never leaves anything DVC could mistake for a result.

``main_guard`` wraps a stage's main so that bad input (:class:`drawer_lib.errors.InputError`)
ends with a one-line message naming the file or value and exit code 2.
"""

import csv
import functools
import json
import math
import os
import random
import resource
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from tqdm import tqdm

from drawer_lib.errors import InputError, NonFiniteError
from drawer_lib.io.atomic import remove_path, replace_path
from drawer_lib.io.images import write_json
from drawer_lib.io.manifest import Manifest
from drawer_lib.paths import LAYOUT, stage_name

EXIT_BAD_INPUT = 2


def seed_everything(seed: int) -> np.random.Generator:
    """Seed Python, NumPy's legacy global state and torch (when imported); return a Generator."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    if "torch" in sys.modules:
        sys.modules["torch"].manual_seed(seed)
    return np.random.default_rng(seed)


def thread_cap() -> int:
    """The threads this process's torch / numba pools may use: ``OMP_NUM_THREADS`` when set (what
    ``make run`` sets per stage), else every core. Part of a result's provenance: the thread
    count changes the order of float sums in parallel reductions."""
    try:
        return max(1, int(os.environ["OMP_NUM_THREADS"]))
    except (KeyError, ValueError):
        return os.cpu_count() or 1


def _own_peak_kib() -> int:
    """This process's own peak resident memory (KiB): Linux's ``VmHWM``, which starts afresh at
    exec. (``ru_maxrss`` keeps the peak of the process that forked it: a stage started by a
    large parent would report the parent's memory.)"""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def peak_rss_mb() -> float:
    """Peak resident memory of this process and of its waited-for children, in MiB."""
    kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return max(_own_peak_kib(), kids) / 1024.0  # KiB on Linux


class Curve:
    """Append-only ``curve.csv`` (``step, wall_s, <columns>``), flushed row by row.

    ``wall_s`` is the time since the stage started unless the caller passes its own clock
    (e.g. training time without the evaluation pauses)."""

    def __init__(self, path: Path, columns: list[str], t0: float):
        self.path, self.columns, self._t0 = path, ["step", "wall_s", *columns], t0
        self._f = open(path, "w", newline="")
        self._w = csv.writer(self._f)
        self._w.writerow(self.columns)
        self._f.flush()

    def log(self, step: int, wall_s: float | None = None, **values: float | None) -> None:
        unknown = set(values) - set(self.columns)
        if unknown:
            raise KeyError(f"curve {self.path.name}: unknown columns {sorted(unknown)}")
        for k, v in values.items():
            if v is not None and not math.isfinite(v):
                raise NonFiniteError(f"curve {self.path.name}: {k} = {v} at step {step}")
        row = [step, f"{(time.perf_counter() - self._t0) if wall_s is None else wall_s:.4f}"]
        row += ["" if values.get(c) is None else f"{values[c]:.6g}" for c in self.columns[2:]]
        self._w.writerow(row)
        self._f.flush()

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()


class StageRun:
    """State of one stage run; see the module doc."""

    def __init__(self, stage: str, out_dir: Path, tmp_dir: Path, seed: int):
        self.stage, self.out_dir, self.dir, self.seed = stage, out_dir, tmp_dir, seed
        self.rng = seed_everything(seed)
        self.metrics: dict = {}
        self.skipped: dict[str, str] = {}
        self.t0 = time.perf_counter()
        self._curves: list[Curve] = []

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def progress(self, iterable: Iterable | None = None, **kw) -> tqdm:
        """A tqdm bar labelled with the stage name (pass ``desc`` to refine it)."""
        desc = f"{self.stage}: {kw.pop('desc')}" if "desc" in kw else self.stage
        return tqdm(iterable, desc=desc, dynamic_ncols=True, mininterval=0.5, **kw)

    def progress_write(self, msg: str) -> None:
        """A log line that does not break the progress bars."""
        tqdm.write(f"[{self.stage}] {msg}", file=sys.stderr)

    def out(self, key: str) -> Path:
        """Where output ``key`` of this stage goes (:data:`drawer_lib.paths.LAYOUT`), inside the
        temporary folder that replaces the stage's folder on success."""
        return self.dir / stage_name(self.stage, key)

    def curve(self, columns: list[str], name: str = LAYOUT["curve"]) -> Curve:
        c = Curve(self.dir / name, columns, self.t0)
        self._curves.append(c)
        return c

    def skip(self, name: str, reason: str) -> None:
        """Record that ``name`` (a metric or a piece of work) was skipped, and why."""
        self.skipped[name] = reason
        print(f"[{self.stage}] skip {name}: {reason}", file=sys.stderr)

    def needs(self, manifest: Manifest, name: str, *requirements: str) -> bool:
        """True when the manifest meets every requirement; else record the skip of ``name``."""
        why = manifest.first_missing(*requirements)
        if why:
            self.skip(name, why)
            return False
        return True

    def _finish(self) -> dict:
        for c in self._curves:
            c.close()
        m = dict(self.metrics)
        for k, v in m.items():
            if isinstance(v, float) and not math.isfinite(v):
                raise NonFiniteError(f"{self.stage}: metric {k} = {v}")
        m["wall_s"] = round(self.elapsed(), 4)
        m["peak_rss_mb"] = round(peak_rss_mb(), 1)
        m["threads"] = thread_cap()
        if self.skipped:
            m["skipped"] = dict(self.skipped)
        write_json(self.dir / LAYOUT["metrics"], m)
        return m


def read_skips(metrics_path: Path) -> dict[str, str]:
    """What a finished stage skipped and why (its ``metrics.json``'s ``skipped``; {} when it
    skipped nothing or has not run)."""
    if not Path(metrics_path).is_file():
        return {}
    skipped = json.loads(Path(metrics_path).read_text()).get("skipped") or {}
    return {str(k): str(v) for k, v in skipped.items()}


_OWNER = ".owner"  # pid of the process writing a temporary folder


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def clean_stale(parent: Path) -> list[Path]:
    """Remove the temporary folders (``.<name>.tmp``) under ``parent`` whose writer is gone (an
    interrupted stage of any kind; a live run elsewhere keeps its own), and put back a result
    whose swap was cut between its two renames (``.<name>.old`` without ``<name>``). Returns the
    removed folders."""
    removed = []
    if not Path(parent).is_dir():
        return removed
    for old in Path(parent).glob(".*.old"):
        final = old.with_name(old.name[1:-len(".old")])
        if not (final.exists() or final.is_symlink()):
            old.rename(final)
    for tmp in Path(parent).glob(".*.tmp"):
        try:
            pid = int((tmp / _OWNER).read_text())
        except (OSError, ValueError):
            pid = -1
        if pid != os.getpid() and (pid <= 0 or not _alive(pid)):
            remove_path(tmp)
            removed.append(tmp)
    return removed


@contextmanager
def stage_run(stage: str, out_dir: Path, seed: int) -> Iterator[StageRun]:
    """Run a stage into a temporary sibling of ``out_dir`` and swap it in on success.

    On the way in, what interrupted runs left in that folder goes (:func:`clean_stale`); SIGTERM
    and SIGHUP (a killed ``dvc repro``, a closed terminal) end the stage like Ctrl-C, removing
    its temporary folder."""
    out_dir = Path(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.parent / f".{out_dir.name}.tmp"
    old = out_dir.parent / f".{out_dir.name}.old"
    clean_stale(out_dir.parent)
    for stale in (tmp, old):  # this stage's own leftovers, whoever wrote them
        remove_path(stale)
    tmp.mkdir()
    (tmp / _OWNER).write_text(str(os.getpid()))
    run = StageRun(stage, out_dir, tmp, seed)
    handlers = _interrupt_on_signals()
    try:
        yield run
        metrics = run._finish()
        (tmp / _OWNER).unlink()
    except BaseException:
        for c in run._curves:
            c.close()
        remove_path(tmp)
        raise
    finally:
        _restore(handlers)
    replace_path(tmp, out_dir, aside=old)  # a cut between its renames: clean_stale puts .old back
    print(f"[{stage}] done in {metrics['wall_s']:.1f} s, peak {metrics['peak_rss_mb']:.0f} MiB -> {out_dir}",
          file=sys.stderr)


def _interrupt_on_signals() -> dict:
    """SIGTERM / SIGHUP raise KeyboardInterrupt (main thread only); returns the old handlers."""
    if threading.current_thread() is not threading.main_thread():
        return {}

    def _raise(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    old = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        old[sig] = signal.signal(sig, _raise)
    return old


def _restore(handlers: dict) -> None:
    for sig, h in handlers.items():
        signal.signal(sig, h)


@contextmanager
def deferred_interrupts() -> Iterator[list[int]]:
    """Ctrl-C, SIGTERM and SIGHUP held back (main thread only): the first is recorded in the
    list it yields, for the caller to stop at its next safe point (a training step's end); a
    second one raises KeyboardInterrupt at once. Elsewhere than the main thread nothing is held
    back and the list stays empty."""
    pending: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield pending
        return

    def _hold(signum, frame):
        if pending:
            raise KeyboardInterrupt(f"signal {signum}")
        pending.append(signum)

    old = {sig: signal.signal(sig, _hold) for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        yield pending
    finally:
        _restore(old)


def main_guard(fn: Callable) -> Callable:
    """Decorator for stage mains: InputError -> ``error: <message>`` on stderr and exit code 2."""

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except InputError as e:
            print(f"error: {e}", file=sys.stderr)
            sys.stderr.flush()
            sys.exit(EXIT_BAD_INPUT)

    return wrapped
