"""Pan/tilt angles at each scan's stamp, interpolated between mount states (no ``rclpy``).

The laser and its pan/tilt mount are two drivers with two clocks of publication: a scan
and the mount state that describes it never carry the same stamp. :class:`MountSync`
keeps the recent mount states (stamp, pan, tilt) and answers for a scan stamp:

* ``(pan, tilt)`` interpolated linearly between the two states that bracket the stamp
  (a state within ``exact`` of the stamp is used as it is), provided the two are at most
  ``max_gap`` apart;
* :data:`WAIT` when the newest state is older than the scan (its bracketing state has not
  arrived yet: the caller keeps the scan and asks again);
* :data:`MISS` with the reason when no pair of states brackets it (older than every state
  kept, or across a gap in the mount's stream): the caller drops the scan and counts it.

Stamps are integer nanoseconds. States must arrive in stamp order; one older than the
newest is ignored (and counted in :attr:`MountSync.out_of_order`).

A scan whose beams are taken one after the other (``LaserScan.time_increment`` > 0) while
the mount moves asks :meth:`MountSync.lookup_beams` for the angles at every beam's time
``stamp + i * time_increment``: each beam is answered as a single stamp would be, and the
scan is ``ok`` only when every beam is (a miss of any beam misses the scan; otherwise it
waits while any beam waits).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

WAIT = "wait"
MISS = "miss"
TOO_OLD = "older than every mount state kept"
"""A miss's reason when the scan predates the states kept (at start: the laser came up first)."""


@dataclass(frozen=True)
class Lookup:
    """The answer for one scan stamp: ``status`` ok / wait / miss, the angles, why missed.

    From :meth:`MountSync.lookup_beams`, ``pan`` and ``tilt`` are arrays, one per beam.
    """

    status: str
    pan: float | np.ndarray = 0.0
    tilt: float | np.ndarray = 0.0
    reason: str = ""


class MountSync:
    """Mount states kept for interpolation (see the module docstring)."""

    def __init__(self, max_gap_ns: int, keep: int = 2000, exact_ns: int = 1000) -> None:
        """Keep the newest ``keep`` states; interpolate across at most ``max_gap_ns``."""
        self.max_gap = int(max_gap_ns)
        self.keep = int(keep)
        self.exact = int(exact_ns)
        self.stamps: list[int] = []
        self.angles: list[tuple[float, float]] = []
        self.out_of_order = 0

    def add(self, stamp_ns: int, pan: float, tilt: float) -> None:
        """A mount state (stamp order; an older one than the newest is ignored)."""
        if self.stamps and stamp_ns <= self.stamps[-1]:
            if stamp_ns == self.stamps[-1]:
                self.angles[-1] = (pan, tilt)
            else:
                self.out_of_order += 1
            return
        self.stamps.append(int(stamp_ns))
        self.angles.append((float(pan), float(tilt)))
        if len(self.stamps) > self.keep:
            del self.stamps[: len(self.stamps) - self.keep]
            del self.angles[: len(self.angles) - self.keep]

    def lookup(self, stamp_ns: int) -> Lookup:
        """The mount's angles at ``stamp_ns`` (or why there are none yet, or none at all)."""
        if not self.stamps:
            return Lookup(WAIT)
        i = bisect.bisect_left(self.stamps, stamp_ns)
        for j in (i - 1, i):
            if 0 <= j < len(self.stamps) and abs(self.stamps[j] - stamp_ns) <= self.exact:
                return Lookup("ok", *self.angles[j])
        if i == len(self.stamps):
            return Lookup(WAIT)
        if i == 0:
            return Lookup(MISS, reason=TOO_OLD)
        t0, t1 = self.stamps[i - 1], self.stamps[i]
        if t1 - t0 > self.max_gap:
            gap = (t1 - t0) * 1e-9
            return Lookup(MISS, reason=f"the mount states around it are {gap:.3f} s apart")
        w = (stamp_ns - t0) / (t1 - t0)
        (p0, a0), (p1, a1) = self.angles[i - 1], self.angles[i]
        return Lookup("ok", p0 + w * (p1 - p0), a0 + w * (a1 - a0))

    def lookup_beams(self, times_ns: np.ndarray) -> Lookup:
        """The mount's angles at every beam's time (``int64 [n]`` ns, any order).

        Each time is answered as :meth:`lookup` answers a stamp; the angles are arrays.
        Any beam missed: :data:`MISS`; else any beam waiting: :data:`WAIT`.
        """
        t = np.asarray(times_ns, dtype=np.int64)
        if not self.stamps or len(t) == 0:
            return Lookup(WAIT)
        s = np.asarray(self.stamps, dtype=np.int64)
        ang = np.asarray(self.angles, dtype=np.float64)
        n = len(s)
        i = np.searchsorted(s, t, side="left")
        prev, nxt = np.clip(i - 1, 0, n - 1), np.clip(i, 0, n - 1)
        exact_prev = (i > 0) & (np.abs(s[prev] - t) <= self.exact)
        exact_next = (i < n) & (np.abs(s[nxt] - t) <= self.exact)
        exact = exact_prev | exact_next
        if ((i == 0) & ~exact).any():
            return Lookup(MISS, reason=TOO_OLD)
        gaps = np.where(exact | (i == n), 0, s[nxt] - s[prev])
        if (gaps > self.max_gap).any():
            gap = int(gaps.max()) * 1e-9
            return Lookup(MISS, reason=f"the mount states around it are {gap:.3f} s apart")
        if ((i == n) & ~exact).any():
            return Lookup(WAIT)
        span = np.where(exact, 1, s[nxt] - s[prev])
        w = np.where(exact, 0.0, (t - s[prev]) / span)[:, None]
        out = ang[prev] + w * (ang[nxt] - ang[prev])
        out = np.where(exact_next[:, None], ang[nxt], out)
        out = np.where(exact_prev[:, None], ang[prev], out)
        return Lookup("ok", out[:, 0], out[:, 1])
