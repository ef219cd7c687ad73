"""SIGINT (Ctrl-C) and SIGTERM: how a run stops, from the command line's first line to the last load step.

The decisions, in the order a run meets them:

- The command line (model.cli.main) installs ``stop_at_once`` for both signals first thing, before numpy, mpi4py,
  dolfinx or gmsh load (``install``): the slow imports of start-up are covered. SIGINT is taken even when the
  process started with it ignored: a non-interactive shell starts a background job (``cmd &``) with SIGINT
  ignored, and ``kill -INT PID`` must still stop the run.
- Outside a run's steps (imports, reading and checking the configuration) a signal stops at once: the handler
  raises StoppedEarly, a BaseException so that no ``except Exception`` around a user's file or a mesh reader
  reports it as an error of that file. The command line prints one line ("interrupted by SIGTERM") and exits
  128 + the signal number (130, 143). No run has begun, so nothing is written.
- Inside a run (model.pipeline.run, membrane runs) a StopFlag takes the signals over: a signal only sets a flag,
  which every rank checks collectively (an allreduce) at fixed points, so all ranks stop at the same point, and
  nothing is raised inside a library (a form's JIT compilation stopped halfway leaves a cache entry that the
  next run waits for; an exception inside a PETSc callback becomes a PETSc error). The pipeline checks after
  ``build`` (mesh generation, fields, forms compiled: a run stopped there leaves its output folder as it found
  it, an earlier run's files included), before the first step (the folder is the run's by then: summary.json
  says "interrupted", last_completed_step 0, or on a restart the step it restarted from), and after every
  attempted step (the step finished and recorded). Each stop raises Interrupted: exit 130 / 143, one line. A
  second SIGINT raises KeyboardInterrupt at once.
- gmsh takes SIGINT over: importing gmsh 4.8 (Debian 12) sets it to SIG_DFL and every ``gmsh.finalize()`` puts
  back the handler of import time; gmsh 4.13's ``initialize`` sets SIG_DFL and ``finalize`` puts back the one
  before. So a Ctrl-C on a gmsh-meshed run killed it without a word (or, SIGINT ignored, a background run went
  on). meshes._gmsh keeps Python's handlers across gmsh's import and every session it opens (meshes'
  ``gmsh_session``, which every generator and .msh / .geo reader uses), and StopFlag.check puts its handlers back
  if anything else replaced them.

Python runs a handler in the main thread between bytecodes: a signal that arrives during a long call into C (a
gmsh mesh generation, a factorisation, a compiler) takes effect when that call returns. A run from Python
(``model.run``) has no ``install``: its StopFlag installs the handlers for the run and restores the caller's after.
"""

from __future__ import annotations

import signal
from typing import Any

#: the signals that stop a run
SIGNALS = (signal.SIGINT, signal.SIGTERM)


def signal_name(signum: int) -> str:
    """SIGINT, SIGTERM, ..."""
    return signal.Signals(signum).name


class Interrupted(Exception):
    """A run stopped by SIGINT or SIGTERM (after the step it was solving, or before its first step; outputs
    closed, summary.json "interrupted" once the output folder is the run's). ``signum``: the signal; a
    command-line exit code is 128 + signum."""

    def __init__(self, signum: int, message: str) -> None:
        super().__init__(message)
        self.signum = signum


class StoppedEarly(BaseException):
    """Raised by ``stop_at_once``, outside a run's steps (module docstring). A BaseException, like
    KeyboardInterrupt: no ``except Exception`` on the way takes it for an error of what it interrupted."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"interrupted by {signal_name(signum)}")
        self.signum = signum


def stop_at_once(signum: int, frame: Any) -> None:
    """The command line's handler: raise StoppedEarly."""
    raise StoppedEarly(signum)


def install() -> dict[int, Any]:
    """Install ``stop_at_once`` for SIGINT and SIGTERM (SIGINT even where it was ignored: module docstring); returns
    the handlers it replaced, for ``restore``. Only the main thread can; elsewhere nothing changes."""
    previous: dict[int, Any] = {}
    try:
        for s in SIGNALS:
            previous[s] = signal.signal(s, stop_at_once)
    except ValueError:  # not the main thread
        pass
    return previous


def restore(previous: dict[int, Any]) -> None:
    """Put back the handlers ``install`` (or anything else) replaced: {signal: handler}."""
    for s, handler in previous.items():
        signal.signal(s, handler if handler is not None else signal.SIG_DFL)


class StopFlag:
    """Catches SIGINT and SIGTERM while a run steps (in the main thread; elsewhere it never triggers): the
    first sets the flag, a second SIGINT raises KeyboardInterrupt at once. ``check(comm)`` is collective:
    the largest signal number any rank got (0: none). On exit the handlers before it are back."""

    def __init__(self) -> None:
        self.signum = 0
        self.previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: Any) -> None:
        if self.signum and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.signum = signum

    def __enter__(self) -> StopFlag:
        try:
            for s in SIGNALS:
                self.previous[s] = signal.signal(s, self._handle)
        except ValueError:  # not the main thread: no handlers
            pass
        return self

    def __exit__(self, *exc: Any) -> None:
        restore(self.previous)

    def check(self, comm: Any) -> int:
        """The largest signal number any rank of ``comm`` got (collective). Puts the flag's handlers back first
        where a library replaced them (gmsh: module docstring)."""
        from mpi4py import MPI

        for s in self.previous:
            if signal.getsignal(s) != self._handle:
                signal.signal(s, self._handle)
        return int(comm.allreduce(self.signum, op=MPI.MAX))
