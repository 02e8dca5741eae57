"""What the companion's search asks of a camera, whichever it is: a MAVLink camera component
(mavlink_camera.py), a video stream or a device (other sources implement the same).

Times are the vehicle's simulated (or, on a real drone, its boot) clock in seconds. A source
with `timed_captures` takes the picture of a given instant when asked ahead (the simulated
camera does: REQUEST_MESSAGE's param 2); one without hands out the latest picture it has and
says when it was taken, or None when it cannot tell."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

Stamped = tuple[np.ndarray | None, float | None]


@runtime_checkable
class FrameSource(Protocol):
    #: ask(at_s) makes the camera take the picture of instant at_s (a SITL camera under the
    #: companion's schedule); False: frames are taken when they are taken (a video stream)
    timed_captures: bool
    requests: int  # asks sent so far (the search log counts them)

    def ask(self, at_s: float) -> None:
        """Ask for the picture of instant at_s, ahead of time; raises CommandRejected when
        the camera refuses (UNSUPPORTED: no timed captures here)."""

    def wait(self, at_s: float, timeout: float) -> Stamped:
        """The first frame taken at or after at_s (an unstamped one as it comes), waiting up
        to `timeout` wall-clock seconds; (None, None) when none came."""

    def capture(self, at_s: float, timeout: float = 1.5, tries: int = 8) -> Stamped:
        """ask + wait, asking again (the camera resends the same picture) until the frame is
        whole or the tries run out; (None, None) then."""

    def request(self, timeout: float = 1.5, tries: int = 8) -> np.ndarray | None:
        """A fresh frame now, untimed; None when `tries` asks of `timeout` s brought none."""

    def close(self) -> None:
        """Stop listening; close what the source opened itself (its own connection)."""


def ask_until_whole(source: FrameSource, at_s: float, timeout: float, tries: int) -> Stamped:
    """Ask for the frame of at_s and wait `timeout` for it, up to `tries` times (a MAVLink
    camera resends the same stamped picture when asked again); (None, None) when none came."""
    for _ in range(tries):
        source.ask(at_s)
        frame, t = source.wait(at_s, timeout)
        if frame is not None:
            return frame, t
    return None, None
