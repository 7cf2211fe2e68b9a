"""Per-frame progress of a running method, for whoever listens (the command line's progress bar).

A method calls ``frame_done(done, total)`` after each frame it has filled (`PerFrameMethod` does it
for its subclasses; a plug-in may call it too). With no listener installed the call costs a context
lookup and does nothing, so methods stay free of any harness: no callback in their signature, no
output of their own. The harness installs a listener for the length of a call::

    with report_frames_to(lambda done, total: bar.update(done - bar.n)):
        method.inpaint(frames, regions)

The listener is held in a `contextvars.ContextVar`, so threads and asyncio tasks running other
methods at the same time do not see each other's progress.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

#: (done, total) -> None: frames finished so far out of the call's total
FrameListener = Callable[[int, int], None]

_LISTENER: ContextVar[FrameListener | None] = ContextVar("dpcbench_frame_listener", default=None)


def frame_done(done: int, total: int) -> None:
    """Tell the listener, if any, that ``done`` of ``total`` frames are filled."""
    listener = _LISTENER.get()
    if listener is not None:
        listener(int(done), int(total))


@contextmanager
def report_frames_to(listener: FrameListener | None) -> Iterator[None]:
    """Install ``listener`` (None: none) for the calls made inside the ``with`` block."""
    token = _LISTENER.set(listener)
    try:
        yield
    finally:
        _LISTENER.reset(token)
