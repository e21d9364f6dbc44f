"""The physical soil under robots that move cell by cell: the offline evaluator's physical world.

``dynamics`` drives robots continuously over the physical soil (:mod:`excavation_sim.soil`)
and lets the grid events follow the bodies; training needs the same soil at the speed of the
grid kernel, with the controller in the loop and no time steps between ticks. Here each
timestep is the grid's (every robot senses, decides, then acts in index order, Table 2
order within a robot), and a move drives the body one cell through the soil in
``subcells`` sub-steps of one sub-cell each, the way ``dynamics`` sees it at a tick's end:

* **Forward.** The grid's refusals first (the new footprint off the site or on a robot;
  with ``refusals``, an engaged blade pushing off the site or into a robot): refused, the
  robot is stuck and nothing moves. Then per sub-step: the force on the blade (McKyes's cut
  and the drag prism, :func:`excavation_sim.soil.blade_force`) and the grade of the body;
  over ``blade_limit`` with ``force_control`` the edge rises until the force is within it;
  when the robot cannot give the push (``blade_limit``, the motor, the wheels) it
  **stalls**: its wheels slip for the drive executor's progress window (they dig in, as in
  ``dynamics``), the robot is stuck (U1) and stays in the cell it has reached (the footprint
  moves once the body is ``commit_fraction`` of a cell ahead, as ``dynamics`` commits a
  move, and the blade's reference ground is measured there). Otherwise the body advances a
  sub-cell and an engaged blade cuts behind its edge.
* **Backward.** The grid's refusals (the cells behind off the site or on a robot); the blade
  leaves its soil. No climb limit or push capacity: the soil and the force decide those.
* **Turns** change the heading; **blade** commands set the blade and measure the edge
  against the front axle's ground (the paper's epsilon rule included), as
  :meth:`excavation_sim.dynamics.Dynamics.set_blade`.
* After each sub-step the bodies (and lowered blades' end plates) block the soil and the
  slopes the robot's move starts relax to the angle of repose until they hold (an
  avalanche worklist, :func:`excavation_sim.soil.relax_local`), where ``dynamics`` sweeps
  the whole field ``relax_passes`` times per integration step; the cells near the robot
  then get their rounded heights (what the controllers sense).

Sensing is the grid's on those rounded heights, except L1 with ``load: force``: the blade's
force over ``load_full_scale`` rescaled to 24 units and rounded, as the sensors node turns
``dynamics``' force into a load. The fitness reads the cells' sub-cell means (``fitness_heights:
mean``) or the rounded heights.

State: the world's arrays (:class:`excavation_sim.world.WorldArrays`) plus one
:class:`SoilArrays`; the soil's constants travel as the float vector :func:`physics_vector`
indexed by the ``X_*`` constants. All kernels are numba-compiled and allocate nothing.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from ant_controller.layout import (
    BLADE_HOME,
    MOVE_BACKWARD,
    MOVE_FORWARD,
    RANDOM_TURN,
    THROTTLE_UP,
    TURN_LEFT,
    TURN_RIGHT,
)
from ant_controller.sensing import (
    FORWARD,
    MAX_LOAD,
    blade_offset,
    blade_volume,
    front_cell,
    in_grid,
    is_tilted_down,
    rear_wheel,
    sense,
)
from excavation_sim.rules import P_H1
from excavation_sim.soil import (
    Site,
    Soil,
    SoilParams,
    _band,
    _local,
    band_ground,
    blade_load,
    body_window,
    cos_sin,
    cut,
    dig_wheels,
    firm_above,
    on_field,
    pile_above,
    relax_local,
    stamp_body,
    volume_above,
)
from excavation_sim.world import (
    BLADE,
    COL,
    HEADING,
    MEMORY,
    ROW,
    STUCK,
    fitness,
    occupied,
    robot_word,
    stamp_footprint,
    turn_and_set,
)

# Indexes of the physics vector (:func:`physics_vector`).
(
    X_CELL, X_SUB, X_S, X_Q, X_UNIT_Q, X_REACH, X_WEDGE_Q, X_GAMMA, X_COHESION, X_N_GAMMA,
    X_N_C, X_N_Q, X_WEDGE, X_DRAG, X_MOTOR0, X_MOTOR1, X_TRACTION, X_MASS, X_GRAVITY,
    X_BLADE_LIMIT, X_FORCE_CONTROL, X_LOAD_SCALE, X_MAX_DIFF, X_TOP, X_FILL, X_REPOSE,
    X_EPSILON, X_REFUSALS, X_LOAD_FORCE, X_FIT_MEAN, X_WING, X_DIG, X_SLIP0, X_SLIP1,
    X_COMMIT,
) = range(35)  # fmt: skip
N_PHYSICS = 35

STALL_SLIP = (0.10, 0.15)
"""Metres a stalled robot's wheels slip, without and with throttle-up: the drive executor's
``progress_window`` (1 s) at its ``max_speed`` and ``throttle_speed`` (drive_executor
defaults), after which it gives the move up as stuck."""

COMMIT_FRACTION = 0.25
"""Travel (cells) past the footprint centre at which a move is made (``dynamics``' default)."""

TURNS = 1 << RANDOM_TURN | 1 << TURN_RIGHT | 1 << TURN_LEFT
"""The behaviour bits that turn a robot."""

# Counters (:attr:`SoilArrays.counters`).
C_MOVES, C_REFUSED, C_STALLS, C_CUT = range(4)
N_COUNTERS = 4

_YAW = np.array([math.pi / 2, 0.0, -math.pi / 2, math.pi])


class SoilArrays(NamedTuple):
    """The physical soil of one world, next to its :class:`~excavation_sim.world.WorldArrays`.

    Attributes:
        fine: ``int64 [rows * s, cols * s]`` sub-cell heights, quanta.
        loose: ``int64`` like ``fine``: the loose part of each sub-cell.
        blocked: ``bool`` like ``fine``: under a robot's body (scratch).
        sums: ``int64 [rows, cols]`` each cell's sub-cell sum (scratch).
        means: ``float64 [rows, cols]`` each cell's mean height, units (the fitness's).
        bodies: ``float64 [n, 3]`` each robot's ``(x, y, yaw)`` (scratch: cell centres
            between moves).
        down: ``bool [n]`` blades lowered (scratch).
        ground: ``int64 [n]`` each blade's reference ground, quanta.
        lift: ``int64 [n]`` each edge's height over that ground, quanta.
        slipped: ``float64 [n]`` slipped metres the wheels have not dug yet.
        counters: ``int64 [N_COUNTERS]`` moves, refusals, stalls, quanta cut.
        physics: ``float64 [N_PHYSICS]`` the constants (:func:`physics_vector`).
        stack: ``int64 [fine.size]`` the repose worklist (scratch).
        queued: ``bool`` like ``fine``: on the worklist (scratch, all False between calls).
        touched: ``int64 [4]`` sub-cell rows and columns a robot's action changed (scratch).
        offset: ``int64 [n]`` sub-cells each body stands ahead of its footprint's centre
            (negative: short of it, after a stall).
        near_u, near_fine, near_loose: ``float64`` / ``int64 [fine.size]``: the sub-cells
            a blade meets, for the force control's search (scratch for :func:`_blade_force`).
        stamped: ``float64 [n, 9]`` each robot's ``(x, y, yaw, down, active)`` as ``blocked``
            last marked it, then that body's window ``(i0, i1, j0, j1)`` when it was last
            stamped (read only while it is active; NaN: never stamped; scratch for
            :func:`_mask`).
    """

    fine: np.ndarray
    loose: np.ndarray
    blocked: np.ndarray
    sums: np.ndarray
    means: np.ndarray
    bodies: np.ndarray
    down: np.ndarray
    ground: np.ndarray
    lift: np.ndarray
    slipped: np.ndarray
    counters: np.ndarray
    physics: np.ndarray
    stack: np.ndarray
    queued: np.ndarray
    touched: np.ndarray
    offset: np.ndarray
    stamped: np.ndarray
    near_u: np.ndarray
    near_fine: np.ndarray
    near_loose: np.ndarray


def physics_vector(
    params: SoilParams,
    cell: float,
    unit: float,
    capacities: tuple[int, int] = (12, 24),
    commit: float = COMMIT_FRACTION,
) -> np.ndarray:
    """The constants of ``params`` (a resolved physical soil) on a site of ``cell`` m cells.

    ``capacities``: the world profile's push capacities (the grid preset's calibration).
    """
    params = params.resolved()
    soil = Soil(np.zeros((1, 1), dtype=np.int64), Site(1, 1, cell, unit), params, None, capacities)
    p = soil.physics
    out = np.zeros(N_PHYSICS)
    out[X_CELL] = cell
    out[X_SUB] = soil.sub
    out[X_S] = soil.s
    out[X_Q] = soil.q
    out[X_UNIT_Q] = unit / soil.q
    out[X_REACH] = params.pile_reach * cell
    out[X_WEDGE_Q] = unit / soil.q * p.wedge
    out[X_GAMMA] = p.gamma
    out[X_COHESION] = p.cohesion
    out[X_N_GAMMA] = p.n_gamma
    out[X_N_C] = p.n_c
    out[X_N_Q] = p.n_q
    out[X_WEDGE] = p.wedge
    out[X_DRAG] = p.drag
    out[X_MOTOR0], out[X_MOTOR1] = p.motor
    out[X_TRACTION] = p.traction()
    out[X_MASS] = p.mass
    out[X_GRAVITY] = p.gravity
    out[X_BLADE_LIMIT] = p.blade_limit
    out[X_FORCE_CONTROL] = params.force_control
    out[X_LOAD_SCALE] = p.load_scale()
    out[X_MAX_DIFF] = soil.max_diff
    out[X_TOP] = soil.top
    out[X_FILL] = params.fill
    out[X_REPOSE] = params.repose
    out[X_EPSILON] = params.epsilon
    out[X_REFUSALS] = params.refusals
    out[X_LOAD_FORCE] = params.load == "force"
    out[X_FIT_MEAN] = params.fitness_heights == "mean"
    out[X_WING] = params.end_plates * cell
    if p.wheels is not None:  # quanta per sub-cell per metre slipped (Soil.dig_in)
        band = round(cell / soil.sub) * round(2 * cell / soil.sub)
        out[X_DIG] = (
            2 * params.contact_width * p.wheels.sinkage / (soil.sub * soil.sub * band)
        ) / unit * soil.q  # fmt: skip
    out[X_SLIP0], out[X_SLIP1] = STALL_SLIP
    out[X_COMMIT] = commit
    return out


@nb.njit(cache=True)
def new_soil(shape, n_robots, physics):
    """Empty :class:`SoilArrays` for a ``(rows, cols)`` world (fill them with :func:`reset`)."""
    s = int(physics[X_S])
    rows = shape[0]
    cols = shape[1]
    fine = np.zeros((rows * s, cols * s), dtype=np.int64)
    return SoilArrays(
        fine,
        np.zeros_like(fine),
        np.zeros(fine.shape, dtype=np.bool_),
        np.zeros((rows, cols), dtype=np.int64),
        np.zeros((rows, cols)),
        np.zeros((n_robots, 3)),
        np.zeros(n_robots, dtype=np.bool_),
        np.zeros(n_robots, dtype=np.int64),
        np.zeros(n_robots, dtype=np.int64),
        np.zeros(n_robots),
        np.zeros(N_COUNTERS, dtype=np.int64),
        physics,
        np.zeros(fine.size, dtype=np.int64),
        np.zeros(fine.shape, dtype=np.bool_),
        np.zeros(4, dtype=np.int64),
        np.zeros(n_robots, dtype=np.int64),
        np.full((n_robots, 9), np.nan),
        np.zeros(fine.size),
        np.zeros(fine.size, dtype=np.int64),
        np.zeros(fine.size, dtype=np.int64),
    )


# --- kernels ---------------------------------------------------------------------------------


@nb.njit(cache=True, inline="always")
def _place(soil, robots, k):
    """Robot k's body: ``offset[k]`` sub-cells ahead of its footprint's centre, heading on."""
    ph = soil.physics
    cell = ph[X_CELL]
    h = robots[k, HEADING]
    ahead = soil.offset[k] * ph[X_SUB]
    soil.bodies[k, 0] = (robots[k, COL] + 1) * cell + ahead * FORWARD[h, 1]
    soil.bodies[k, 1] = (robots[k, ROW] + 1) * cell + ahead * FORWARD[h, 0]
    soil.bodies[k, 2] = _YAW[h]


@nb.njit(cache=True, _nrt=False)
def reset(soil, heights, robots, active):
    """Start the soil from the whole-unit ``heights`` (each cell's sub-cells level, all firm).

    The bodies block their soil and the field relaxes once, as ``dynamics`` starts; then
    ``heights`` becomes the rounded cell means and every blade's edge is measured.
    """
    ph = soil.physics
    s = int(ph[X_S])
    q = int(ph[X_Q])
    rows, cols = heights.shape
    for r in range(rows):
        for c in range(cols):
            for a in range(s):
                for b in range(s):
                    soil.fine[r * s + a, c * s + b] = heights[r, c] * q
    soil.loose[:] = 0
    soil.counters[:] = 0
    soil.slipped[:] = 0.0
    soil.offset[:] = 0
    for k in range(robots.shape[0]):
        _place(soil, robots, k)
        soil.down[k] = robots[k, BLADE] != BLADE_HOME
    soil.blocked[:] = False
    soil.stamped[:] = np.nan
    _mask(soil, active)
    _relax(soil, 0, soil.fine.shape[0], 0, soil.fine.shape[1])
    _refresh(soil, heights, 0, rows, 0, cols)
    for k in range(robots.shape[0]):
        _measure(soil, robots, k)


@nb.njit(cache=True, inline="always")
def _unchanged(soil, active, k):
    """Whether robot k's body is where ``blocked`` last marked it."""
    st = soil.stamped
    b = soil.bodies
    return (
        st[k, 0] == b[k, 0] and st[k, 1] == b[k, 1] and st[k, 2] == b[k, 2]
        and st[k, 3] == (1.0 if soil.down[k] else 0.0) and st[k, 4] == (1.0 if active[k] else 0.0)
    )  # fmt: skip


@nb.njit(cache=True, inline="always")
def _window(st, k):
    """The window :func:`_mask` stored for robot k's body when it last stamped it."""
    return int(st[k, 5]), int(st[k, 6]), int(st[k, 7]), int(st[k, 8])


@nb.njit(cache=True, _nrt=False)
def _mask(soil, active):
    """Mark the sub-cells under the bodies (and lowered blades' end plates) as blocked.

    The same mask as :func:`excavation_sim.soil.body_mask` (a union of the bodies'
    stamps), updated where bodies changed since the last call: a changed body's old window
    is cleared, then it and every body whose window meets a cleared one are stamped again.
    Each active body's window is computed once, when it is stamped (``stamped[:, 5:]``): a
    body that did not change still stands in it.
    """
    ph = soil.physics
    cell = ph[X_CELL]
    sub = ph[X_SUB]
    wing = ph[X_WING]
    mask = soil.blocked
    rows, cols = mask.shape
    st = soil.stamped
    n = soil.bodies.shape[0]
    changed = 0
    for k in range(n):
        if not _unchanged(soil, active, k):
            changed |= 1 << k
    if changed == 0:
        return
    cleared = 0
    for k in range(n):
        if changed >> k & 1 and st[k, 4] == 1.0:
            i0, i1, j0, j1 = _window(st, k)
            mask[i0:i1, j0:j1] = False
            cleared |= 1 << k
    for m in range(n):
        if not active[m]:
            continue
        again = changed >> m & 1 == 1
        if not again and cleared:
            a0, a1, b0, b1 = _window(st, m)  # unchanged: where it was stamped
            for k in range(n):
                if cleared >> k & 1:
                    i0, i1, j0, j1 = _window(st, k)
                    if a0 < i1 and i0 < a1 and b0 < j1 and j0 < b1:
                        again = True
                        break
        if again:
            stamp_body(
                mask, soil.bodies[m, 0], soil.bodies[m, 1], soil.bodies[m, 2], sub, cell, cell,
                soil.down[m], wing,
            )  # fmt: skip
    bodies = soil.bodies
    for k in range(n):
        if changed >> k & 1:
            st[k, 0] = bodies[k, 0]
            st[k, 1] = bodies[k, 1]
            st[k, 2] = bodies[k, 2]
            st[k, 3] = 1.0 if soil.down[k] else 0.0
            st[k, 4] = 1.0 if active[k] else 0.0
            if not active[k]:
                continue  # not stamped: its window is never read
            i0, i1, j0, j1 = body_window(
                bodies[k, 0], bodies[k, 1], bodies[k, 2], sub, cell, cell, wing, rows, cols
            )  # fmt: skip
            st[k, 5] = i0
            st[k, 6] = i1
            st[k, 7] = j0
            st[k, 8] = j1


@nb.njit(cache=True, inline="always")
def _relax(soil, i0, i1, j0, j1):
    """Settle the slopes that sub-cells ``[i0:i1, j0:j1]`` start (``repose`` on)."""
    ph = soil.physics
    if ph[X_REPOSE] == 0:
        return
    relax_local(
        soil.fine, soil.loose, soil.blocked, int(ph[X_MAX_DIFF]), i0, i1, j0, j1,
        soil.stack, soil.queued, soil.touched,
    )  # fmt: skip


@nb.njit(cache=True, inline="always")
def _relax_band(soil, k, u0, u1):
    """Settle the slopes started in the band ``u0 <= u < u1`` m ahead of robot k's centre.

    The band spans the body's width and a sub-cell more on each side (headings are
    axis-aligned, so it is a window of whole sub-cells).
    """
    ph = soil.physics
    sub = ph[X_SUB]
    half = ph[X_CELL] + sub
    x = soil.bodies[k, 0]
    y = soil.bodies[k, 1]
    c, sn = cos_sin(soil.bodies[k, 2])
    xa = x + u0 * c
    xb = x + u1 * c
    ya = y + u0 * sn
    yb = y + u1 * sn
    x0 = min(xa, xb) - half * abs(sn)
    x1 = max(xa, xb) + half * abs(sn)
    y0 = min(ya, yb) - half * abs(c)
    y1 = max(ya, yb) + half * abs(c)
    rows, cols = soil.fine.shape
    i0 = max(int(math.floor(y0 / sub + 1e-9)), 0)
    i1 = min(int(math.ceil(y1 / sub - 1e-9)), rows)
    j0 = max(int(math.floor(x0 / sub + 1e-9)), 0)
    j1 = min(int(math.ceil(x1 / sub - 1e-9)), cols)
    if i0 < i1 and j0 < j1:
        _touch(soil, i0, i1 - 1, j0, j1 - 1)
        _relax(soil, i0, i1, j0, j1)


@nb.njit(cache=True, inline="always")
def _touch(soil, i0, i1, j0, j1):
    """Grow :attr:`SoilArrays.touched` over sub-cell rows ``i0..i1`` and columns ``j0..j1``."""
    t = soil.touched
    t[0] = min(t[0], i0)
    t[1] = max(t[1], i1)
    t[2] = min(t[2], j0)
    t[3] = max(t[3], j1)


@nb.njit(cache=True, inline="always")
def _refresh(soil, heights, r0, r1, c0, c1):
    """Cells ``[r0:r1, c0:c1]``: their sums, means and rounded heights (halves up)."""
    ph = soil.physics
    s = int(ph[X_S])
    per_cell = s * s * int(ph[X_Q])
    for r in range(r0, r1):
        for c in range(c0, c1):
            total = 0
            for a in range(s):
                for b in range(s):
                    total += on_field(soil.fine, r * s + a, c * s + b)
            soil.sums[r, c] = total
            soil.means[r, c] = total / per_cell
            heights[r, c] = (2 * total + per_cell) // (2 * per_cell)


@nb.njit(cache=True, inline="always")
def _edge(soil, k):
    return soil.ground[k] + soil.lift[k]


@nb.njit(cache=True, _nrt=False)
def _measure(soil, robots, k):
    """Robot k's blade edge, set against its front axle's ground where it stands now."""
    ph = soil.physics
    cell = ph[X_CELL]
    x = soil.bodies[k, 0]
    y = soil.bodies[k, 1]
    yaw = soil.bodies[k, 2]
    total, n = band_ground(soil.fine, x, y, yaw, ph[X_SUB], 0.0, cell / 2, cell)
    soil.ground[k] = total // n if n else 0
    offset = blade_offset(robots[k, BLADE])
    soil.lift[k] = offset * int(ph[X_Q])
    if ph[X_EPSILON] != 0 and offset > 0:
        held = volume_above(
            soil.fine, x, y, yaw, ph[X_SUB], cell, cell, ph[X_REACH], _edge(soil, k)
        )
        if held == 0:
            soil.lift[k] = 0


@nb.njit(cache=True, inline="always")
def _load(soil, x, y, yaw, edge):
    """``(depth, force)``: the blade's cut depth (quanta) and force (N) at an edge.

    :func:`excavation_sim.soil.blade_load` with the soil's constants, then its force.
    """
    ph = soil.physics
    cell = ph[X_CELL]
    depth, over, beyond = blade_load(
        soil.fine, soil.loose, x, y, yaw, ph[X_SUB], cell, cell, ph[X_REACH], edge, ph[X_WEDGE_Q]
    )  # fmt: skip
    return depth, _load_force(ph, depth, over, beyond)


@nb.njit(cache=True, _nrt=False)
def force_at(soil, x, y, yaw, edge):
    """The blade's force (N) at ``(x, y, yaw)`` with its edge at ``edge`` quanta."""
    return _load(soil, x, y, yaw, edge)[1]


@nb.njit(cache=True, inline="always")
def _load_force(ph, depth, over, beyond):
    """The force (N) of :func:`excavation_sim.soil.blade_load`'s ``(depth, over, beyond)``."""
    cell = ph[X_CELL]
    sub = ph[X_SUB]
    unit = ph[X_UNIT_Q]
    d = depth * unit
    volume = unit * sub * sub
    width = 2.0 * cell
    gamma = ph[X_GAMMA]
    force = ph[X_DRAG] * gamma * beyond * volume
    if d > 0.0:
        length = d * ph[X_WEDGE]
        q = gamma * over * volume / (width * length) if length > 0.0 else 0.0
        force += width * (
            gamma * d * d * ph[X_N_GAMMA] + ph[X_COHESION] * d * ph[X_N_C] + q * d * ph[X_N_Q]
        )
    return force


@nb.njit(cache=True, _nrt=False)
def _gather(soil, x, y, yaw, depth):
    """Store the sub-cells :func:`excavation_sim.soil.blade_load` reads at an edge.

    ``depth``: the cut depth ``blade_load`` gave there (it sets how far ahead it reads).
    Their ``u`` (m ahead), heights and loose soil go to ``near_*``; returns how many. An
    edge at or above that edge reads a subset of them (:func:`_near_force`).
    """
    ph = soil.physics
    cell = ph[X_CELL]
    sub = ph[X_SUB]
    reach = ph[X_REACH]
    front = cell
    half_width = cell
    length = depth * ph[X_WEDGE_Q]
    far = length if length > reach else reach
    rows, cols = soil.fine.shape
    cy, sy = cos_sin(yaw)
    i0, i1, j0, j1, every = _band(x, y, cy, sy, front, front + far, half_width, sub, rows, cols)
    m = 0
    for i in range(i0, i1):
        for j in range(j0, j1):
            u, v = _local(i, j, sub, x, y, cy, sy)
            if not every and (abs(v) >= half_width or u < front or u >= front + far):
                continue
            soil.near_u[m] = u
            soil.near_fine[m] = on_field(soil.fine, i, j)
            soil.near_loose[m] = on_field(soil.loose, i, j)
            m += 1
    return m


@nb.njit(cache=True, _nrt=False)
def _near_force(soil, m, edge):
    """:func:`force_at` from the ``m`` sub-cells :func:`_gather` stored (at an edge as high).

    The same sums over the same sub-cells as :func:`excavation_sim.soil.blade_load`
    (integers, so in any order), hence the same force.
    """
    ph = soil.physics
    cell = ph[X_CELL]
    sub = ph[X_SUB]
    reach = ph[X_REACH]
    front = cell
    cut_total = 0
    cut_n = 0
    for a in range(m):
        if soil.near_u[a] < front + sub:
            cut_total += firm_above(soil.near_fine[a], soil.near_loose[a], edge)
            cut_n += 1
    depth = cut_total / cut_n if cut_n else 0.0
    length = depth * ph[X_WEDGE_Q]
    far = length if length > reach else reach
    over = 0
    beyond = 0
    for a in range(m):
        u = soil.near_u[a]
        if u >= front + far:
            continue
        pile = pile_above(soil.near_fine[a], soil.near_loose[a], edge)
        if pile == 0:
            continue
        if u < front + length:
            over += pile
        else:
            beyond += pile
    return _load_force(ph, depth, over, beyond)


@nb.njit(cache=True, _nrt=False)
def _blade_force(soil, robots, k):
    """Robot k's blade force where it stands (0 with the blade home); force control on."""
    if robots[k, BLADE] == BLADE_HOME:
        return 0.0
    ph = soil.physics
    x = soil.bodies[k, 0]
    y = soil.bodies[k, 1]
    yaw = soil.bodies[k, 2]
    base = _edge(soil, k)
    depth, force = _load(soil, x, y, yaw, base)
    limit = ph[X_BLADE_LIMIT]
    if ph[X_FORCE_CONTROL] != 0 and limit > 0.0 and force > limit:
        # the blade's force control lifts the edge until the force is within its limit
        # (Soil.relief: bisection on whole quanta up to 8 units)
        # (the probes read the sub-cells the blade meets at its edge, stored once)
        m = _gather(soil, x, y, yaw, depth) if ph[X_REACH] >= ph[X_SUB] else -1
        low = 0
        high = 8 * int(ph[X_Q])
        at_high = math.nan  # the probe at ``high`` once one was taken there
        while high - low > 1:
            mid = (low + high) // 2
            if m >= 0:
                probe = _near_force(soil, m, base + mid)
            else:
                probe = force_at(soil, x, y, yaw, base + mid)
            if probe <= limit:
                high = mid
                at_high = probe
            else:
                low = mid
        soil.lift[k] += high
        if not math.isnan(at_high):
            force = at_high
        elif m >= 0:
            force = _near_force(soil, m, _edge(soil, k))
        else:
            force = force_at(soil, x, y, yaw, _edge(soil, k))
    return force


@nb.njit(cache=True, _nrt=False)
def _pitch(soil, x, y, yaw):
    """The body's nose-up pitch (rad): front row's mean ground against the rear row's."""
    ph = soil.physics
    cell = ph[X_CELL]
    front, n_front = band_ground(soil.fine, x, y, yaw, ph[X_SUB], 0.0, cell, cell)
    rear, n_rear = band_ground(soil.fine, x, y, yaw, ph[X_SUB], -cell, 0.0, cell)
    if n_front == 0 or n_rear == 0:
        return 0.0
    rise = (front / n_front - rear / n_rear) * ph[X_UNIT_Q]
    return math.atan2(rise, cell)


@nb.njit(cache=True, inline="always")
def _stalls(soil, blade, demand, throttle):
    """Whether a robot cannot give ``demand`` N (``blade`` of it on the blade)."""
    ph = soil.physics
    limit = ph[X_BLADE_LIMIT]
    if limit > 0.0 and blade > limit:
        return True
    motor = ph[X_MOTOR1] if throttle else ph[X_MOTOR0]
    available = motor if motor < ph[X_TRACTION] else ph[X_TRACTION]
    return demand > available


@nb.njit(cache=True, inline="always")
def _dig_in(soil, k, throttle):
    """A stalled robot's wheels slip for the executor's progress window and dig in."""
    ph = soil.physics
    per_metre = ph[X_DIG]
    if per_metre <= 0.0:
        return
    metres = soil.slipped[k] + (ph[X_SLIP1] if throttle else ph[X_SLIP0])
    take = int(metres * per_metre)
    if take > 0:
        cell = ph[X_CELL]
        dig_wheels(
            soil.fine, soil.loose, soil.bodies[k, 0], soil.bodies[k, 1], soil.bodies[k, 2],
            ph[X_SUB], cell, cell, take,
        )  # fmt: skip
        metres -= take / per_metre
    soil.slipped[k] = metres


@nb.njit(cache=True, inline="always")
def _footprint_free(robots, occ, k, rows, cols, sign, engaged):
    """Whether robot k's footprint may move one cell (``sign`` +1 ahead, -1 behind)."""
    row = robots[k, ROW]
    col = robots[k, COL]
    h = robots[k, HEADING]
    fr = FORWARD[h, 0]
    fc = FORWARD[h, 1]
    for i in range(2):
        if sign > 0:
            r, c = front_cell(row, col, h, i)
        else:
            r, c = rear_wheel(row, col, h, i)
            r -= fr
            c -= fc
        if not in_grid(rows, cols, r, c) or occupied(occ, k, r, c):
            return False
        if engaged and not (
            in_grid(rows, cols, r + fr, c + fc) and not occupied(occ, k, r + fr, c + fc)
        ):
            return False
    return True


@nb.njit(cache=True, inline="always")
def _commit(robots, occ, k, sign):
    """Move robot k's footprint one cell (``sign`` +1 ahead, -1 behind)."""
    h = robots[k, HEADING]
    row = robots[k, ROW]
    col = robots[k, COL]
    stamp_footprint(occ, row, col, 0)
    robots[k, ROW] = row + sign * FORWARD[h, 0]
    robots[k, COL] = col + sign * FORWARD[h, 1]
    stamp_footprint(occ, robots[k, ROW], robots[k, COL], k + 1)


@nb.njit(cache=True, inline="always")
def _cut(soil, k):
    """Robot k's blade cuts where it stands (:func:`excavation_sim.soil.cut`).

    Soil standing more than the blade's height over its edge falls behind it. Returns the
    quanta cut.
    """
    ph = soil.physics
    cell = ph[X_CELL]
    return cut(
        soil.fine, soil.loose, soil.blocked, soil.bodies[k, 0], soil.bodies[k, 1],
        soil.bodies[k, 2], ph[X_SUB], cell, cell, _edge(soil, k), int(ph[X_TOP]), ph[X_FILL] != 0,
    )  # fmt: skip


@nb.njit(cache=True, _nrt=False)
def drive(heights, robots, active, occ, k, sign, throttle, soil):
    """Drive robot k to the centre of the cell ahead (``sign`` 1) or behind (-1).

    The body goes a sub-cell per sub-step from where it stands (a body that stalled after
    its footprint moved stands short of its footprint's centre, as in ``dynamics``); the
    footprint moves once the body is ``commit_fraction`` of a cell past its centre.

    Returns:
        ``(moved, changed, stalled)``: the footprint moved a cell, anything changed (a
        stall counts: the wheels slipped; a refusal does not), and the robot stalled on
        the way (before or after its footprint moved: the executor's stuck event either way).
    """
    ph = soil.physics
    rows, cols = heights.shape
    engaged = robots[k, BLADE] != BLADE_HOME
    refuse_engaged = sign > 0 and engaged and ph[X_REFUSALS] != 0
    if not _footprint_free(robots, occ, k, rows, cols, sign, refuse_engaged):
        soil.counters[C_REFUSED] += 1
        return False, False, False
    s = int(ph[X_S])
    sub = ph[X_SUB]
    cell = ph[X_CELL]
    commit = max(int(math.ceil(ph[X_COMMIT] * s - 1e-9)), 1)
    yaw = soil.bodies[k, 2]
    big = soil.fine.shape[0] + soil.fine.shape[1]
    soil.touched[0] = big
    soil.touched[1] = -1
    soil.touched[2] = big
    soil.touched[3] = -1
    off = soil.offset[k]
    moved = False
    changed = False
    stalled = False
    for _ in range(s - sign * off):
        if sign > 0:
            blade = _blade_force(soil, robots, k) if engaged else 0.0
            pitch = _pitch(soil, soil.bodies[k, 0], soil.bodies[k, 1], yaw)
            grade = ph[X_MASS] * ph[X_GRAVITY] * math.sin(pitch)
            if _stalls(soil, blade, blade + grade, throttle):
                soil.counters[C_STALLS] += 1
                _dig_in(soil, k, throttle)
                _relax_band(soil, k, -2.0 * cell - 2.0 * sub, sub)
                changed = True
                stalled = True
                break
        off += sign
        soil.offset[k] = off
        _place(soil, robots, k)
        changed = True
        if sign > 0 and engaged:
            soil.counters[C_CUT] += _cut(soil, k)
        if not moved and sign * off >= commit:
            _commit(robots, occ, k, sign)
            off -= sign * s
            soil.offset[k] = off  # the same place, from the new footprint's centre
            moved = True
            soil.counters[C_MOVES] += 1
            _measure(soil, robots, k)
        _mask(soil, active)
        _relax_band(soil, k, cell - 3.0 * sub, cell + 2.0 * sub)  # the blade's cut
        _relax_band(soil, k, -cell - 2.0 * sub, -cell + 2.0 * sub)  # left behind the body
    if soil.touched[1] >= 0:
        _refresh(
            soil, heights, soil.touched[0] // s, min(soil.touched[1] // s + 1, rows),
            soil.touched[2] // s, min(soil.touched[3] // s + 1, cols),
        )  # fmt: skip
    return moved, changed, stalled


@nb.njit(cache=True, _nrt=False)
def step_robot(heights, robots, active, occ, k, mask, rng, soil):
    """Run robot k's selected behaviours (bit mask) in Table 2 order on the physical soil.

    As :func:`excavation_sim.world.step_robot`: U1 becomes 1 when a move this timestep was
    refused or stalled (also where the stall came after the footprint moved). Returns
    False when the world is exactly as before.
    """
    if not active[k]:
        return False
    throttle = (mask >> THROTTLE_UP) & 1 == 1
    stuck = 0
    changed = (mask >> RANDOM_TURN) & 1 == 1
    blade = robots[k, BLADE]
    word = robot_word(robots, k)
    for sign in (1, -1):
        if (mask >> (MOVE_FORWARD if sign > 0 else MOVE_BACKWARD)) & 1:
            moved, soil_changed, stalled = drive(
                heights, robots, active, occ, k, sign, throttle, soil
            )
            if stalled or not moved:
                stuck = 1
            if soil_changed:
                changed = True
    turn_and_set(robots, k, mask, rng)
    if mask & TURNS:  # a turn starts from the footprint's centre (a short body is set there)
        soil.offset[k] = 0
        _place(soil, robots, k)
    if robots[k, BLADE] != blade:
        soil.down[k] = robots[k, BLADE] != BLADE_HOME
        _measure(soil, robots, k)
    robots[k, STUCK] = stuck
    return changed or robot_word(robots, k) != word


@nb.njit(cache=True, _nrt=False)
def step_robots(heights, robots, active, occ, masks, rng, soil):
    """Apply every robot's behaviour mask in index order (robot 0 first).

    Returns False when nothing changed (then every later timestep does nothing either).
    """
    changed = False
    for k in range(robots.shape[0]):
        if step_robot(heights, robots, active, occ, k, masks[k], rng, soil):
            changed = True
    return changed


@nb.njit(cache=True, _nrt=False)
def load_volume(soil, heights, robots, k):
    """What L1 reads for robot k: the blade's force rescaled to units, or the grid's volume."""
    ph = soil.physics
    if ph[X_LOAD_FORCE] == 0:
        return blade_volume(
            heights, robots[k, ROW], robots[k, COL], robots[k, HEADING], robots[k, BLADE]
        )
    if robots[k, BLADE] == BLADE_HOME:
        return 0
    x = soil.bodies[k, 0]
    y = soil.bodies[k, 1]
    force = force_at(soil, x, y, soil.bodies[k, 2], _edge(soil, k))
    return int(np.rint(max(force, 0.0) / ph[X_LOAD_SCALE] * MAX_LOAD))  # as messages.py


@nb.njit(cache=True, _nrt=False)
def sense_robot(heights, zones, goal, robots, active, k, out, params, soil):
    """Robot k's sensor vector on the physical soil (the rounded heights; L1 as it reads)."""
    row = robots[k, ROW]
    col = robots[k, COL]
    h = robots[k, HEADING]
    sense(
        heights,
        zones,
        goal,
        robots,
        active,
        k,
        robots[k, BLADE],
        load_volume(soil, heights, robots, k),
        robots[k, STUCK],
        is_tilted_down(heights, row, col, h),
        robots[k, MEMORY],
        out,
        params[P_H1],
    )


@nb.njit(cache=True, _nrt=False)
def soil_fitness(soil, heights, zones, goal):
    """The paper's fitness of the physical world (``fitness_heights``: means or rounded)."""
    if soil.physics[X_FIT_MEAN] != 0:
        return fitness(soil.means, zones, goal)
    return fitness(heights, zones, goal)


def total_quanta(soil: SoilArrays) -> int:
    """All soil in the field, quanta (conserved by every kernel)."""
    return int(soil.fine.sum())
