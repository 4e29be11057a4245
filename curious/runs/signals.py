"""Work that a stopping signal must not cut half-way: the signal is taken once it has ended.

A Ctrl-C is a `KeyboardInterrupt` raised wherever Python happens to be. Inside `torch.save` onto
an open file that can end the process outright: the exception unwinds out of the zip writer
before its end record is written, the file is closed on the way out, and the writer's C++
destructor then writes that record to the closed file, which aborts the process (`terminate
called after throwing an instance of 'pybind11::error_already_set' ... write to closed file`,
exit status 134), where it should have stopped the run at its last checkpoint. Raised a little
earlier, the interrupt surfaces as torch's "unexpected pos" `RuntimeError`, a write failure
rather than a Ctrl-C. `signals_held` sets Python's handlers aside while such work runs, and
raises each signal that came again once it has ended, for the handler that was there before.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

STOPPING_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals that stop a process (Ctrl-C, `kill`, a closed terminal)."""


def in_main_thread() -> bool:
    """Whether signal handlers can be set here (Python runs them in the main thread only)."""
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """The stopping signals that come while the block runs taken only once it has ended, each
    once, by the handler that was set before (a Ctrl-C is then a `KeyboardInterrupt` right after
    the block). Python's handlers are set aside rather than the signals blocked, since any of the
    process's threads (pyarrow's, torch's) may receive a signal. Outside the main thread, where
    Python takes no signal, the block runs as it is."""
    if not in_main_thread():
        yield
        return
    caught: list[int] = []
    previous = {sig: signal.signal(sig, lambda n, f: caught.append(n)) for sig in STOPPING_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        for sig in dict.fromkeys(caught):
            signal.raise_signal(sig)
