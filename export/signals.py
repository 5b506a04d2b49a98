"""Signals and child processes: SIGTERM and SIGHUP end a run as SIGINT does; workers die with it.

``install()`` (called by ``nupatch``'s ``main`` and by every ``-j`` worker) makes SIGTERM and
SIGHUP raise ``Terminated``, a ``KeyboardInterrupt``: the same unwinding as Ctrl-C, so that
``export.atomic.atomic_output`` removes its temporary file, an old output stays as it was, and
``main`` prints one line (``nupatch: terminated by SIGTERM``) and exits 128 + the signal number
(143, 129), as a shell reports a process killed by it.

Python runs signal handlers in the main thread between bytecodes, so a signal that arrives
during one long OpenCASCADE call (a STEP write of minutes) would wait for the call to end.
A watchdog thread therefore reads the interpreter's wakeup descriptor (``signal.set_wakeup_fd``,
written by the C-level handler at once): if the main thread has not finished unwinding
``GRACE`` seconds after SIGTERM or SIGHUP, the watchdog removes the temporary files this
process has open (``export.atomic.live_temporaries``), prints the same line and ends the
process with ``os._exit``.

Workers of ``build -j N`` come from ``worker_pool``: each asks the kernel for SIGTERM when its
parent dies (``prctl(PR_SET_PDEATHSIG)`` through ctypes, Linux), and checks its parent once
after asking (the parent may have died before); elsewhere a thread polls ``os.getppid()``.
The parent itself, when interrupted, terminates its workers instead of waiting for them.
SIGKILL cannot be handled: a temporary file it leaves is named by
``export.atomic.temporary_name`` and removed by the next run on that output.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING, Iterator

if TYPE_CHECKING:  # imported by worker_pool: multiprocessing is ~4 ms of every start
    from concurrent.futures import ProcessPoolExecutor

from export.atomic import live_temporaries

__all__ = ["GRACE", "HANDLED", "Terminated", "install", "worker_pool", "die_with_parent"]

#: Signals handled like SIGINT.
HANDLED = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))
#: Seconds the main thread has to unwind after SIGTERM/SIGHUP before the watchdog ends the process.
GRACE = 2.0
_PR_SET_PDEATHSIG = 1
_INSTALLED: list[int] = []  # the pid that installed the handlers (a forked worker installs its own)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: unwinds like Ctrl-C (temporary files removed), exit 128 + signum."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    @property
    def message(self) -> str:
        return f"terminated by {signal.Signals(self.signum).name}"


def _raise(signum: int, frame) -> None:
    for s in HANDLED:  # one signal unwinds once: a second SIGTERM must not interrupt the cleanup
        signal.signal(s, signal.SIG_IGN)
    raise Terminated(signum)


def _last_resort(signum: int) -> None:
    for name in list(live_temporaries()):
        with contextlib.suppress(OSError):
            os.unlink(name)
    with contextlib.suppress(OSError):
        os.write(2, f"nupatch: {Terminated(signum).message}\n".encode())
    os._exit(128 + signum)


def _watch(read_fd: int) -> None:
    while True:
        try:
            data = os.read(read_fd, 64)
        except OSError:
            return
        if not data:
            return
        for signum in data:
            if signum in HANDLED:
                deadline = time.monotonic() + GRACE
                while time.monotonic() < deadline:
                    time.sleep(0.05)
                _last_resort(signum)


def install() -> None:
    """Handle SIGTERM and SIGHUP like SIGINT in this process (module docstring); main thread only."""
    if threading.current_thread() is not threading.main_thread() or _INSTALLED == [os.getpid()]:
        return
    _INSTALLED[:] = [os.getpid()]
    for s in HANDLED:
        signal.signal(s, _raise)
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    threading.Thread(target=_watch, args=(read_fd,), daemon=True, name="nupatch-signals").start()


def die_with_parent(parent: int) -> None:
    """Ask for SIGTERM when the parent process ``parent`` ends (Linux prctl, else a polling
    thread); if it has already ended, terminate now."""
    asked = False
    if sys.platform.startswith("linux"):
        with contextlib.suppress(Exception):
            asked = ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) == 0
    if os.getppid() != parent:  # the parent died before prctl took effect
        os.kill(os.getpid(), signal.SIGTERM)
    if not asked:
        def poll() -> None:
            while os.getppid() == parent:
                time.sleep(0.5)
            os.kill(os.getpid(), signal.SIGTERM)

        threading.Thread(target=poll, daemon=True, name="nupatch-parent").start()


def _worker_init(parent: int) -> None:
    install()
    signal.signal(signal.SIGINT, signal.default_int_handler)
    die_with_parent(parent)


@contextlib.contextmanager
def worker_pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A ProcessPoolExecutor whose workers handle signals like ``nupatch`` and die with it;
    leaving the block by an exception (Ctrl-C, SIGTERM) terminates them rather than waiting."""
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(max_workers=workers, initializer=_worker_init, initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        processes = list(getattr(pool, "_processes", {}).values())  # stdlib attribute: no public handle
        pool.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            with contextlib.suppress(Exception):
                p.terminate()
        for p in processes:
            with contextlib.suppress(Exception):
                p.join(GRACE + 1.0)
        raise
    else:
        pool.shutdown(wait=True)
