"""Whether the estimate is the only place the scans allow: the rival check, the map's twins and the two cases in
which the check moves particles. The feature filter (feature_filter.py) asks it once per measurement update.

The rival check (rivals.py) keeps the recent scans and the look-alike places they cannot rule out; a localized
reading with one standing becomes ``ambiguous``. Candidates are the filter's other modes, its best particles away
from the estimate, the fingerprint suggestions and, for a localized reading, the map's own twins of the place
(twins.py). A rival that leads an estimate never reported localized since its last jump decisively
(``RivalConfig.switch``) takes the estimate's mode; a held estimate the kept scans favour keeps its place when the
filter's best particles move elsewhere (``RivalConfig.hold``). Whether the estimate is held is this module's state:
``after`` is told each update's reported status.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from pimm_agents.localizer import Hypothesis
from pimm_agents.particles.belief import BeliefReading, Confirmation, read_belief
from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.pimm.rival_config import RivalConfig
from pimm_agents.pimm.rivals import RivalTracker
from pimm_agents.pimm.twins import MapTwins
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.occupancy import OccupancyGrid

Result = TypeVar("Result")


def _timed(method: Callable[..., Result]) -> Callable[..., Result]:
    """A method of the check whose running time is added to ``spent_ms``."""

    @functools.wraps(method)
    def timed(self: AmbiguityCheck, *args: Any, **kwargs: Any) -> Result:
        start = time.perf_counter()
        try:
            return method(self, *args, **kwargs)
        finally:
            self.spent_ms += 1000 * (time.perf_counter() - start)

    return timed


def rival_hypothesis(place: np.ndarray) -> Hypothesis:
    """A rival place as a hypothesis: weight 0 (the filter holds no particles there), 0.5 m and 10 deg (1 sigma)."""
    return Hypothesis(
        float(place[0]), float(place[1]), float(place[2]), 0.0, np.diag([0.25, 0.25, np.radians(10.0) ** 2])
    )


class AmbiguityCheck:
    """The rival check of one filter (``check``, called with the filter after its measurement update), with the
    map's twins and whether the estimate is held (reported localized since it last jumped)."""

    def __init__(
        self, occupancy: OccupancyGrid, wall_field: LikelihoodField, temperature: float, config: RivalConfig
    ) -> None:
        #: look-alike places the recent scans cannot tell from the estimate (rivals.py)
        self.tracker = RivalTracker(wall_field, occupancy.free, temperature, config)
        self.twins = MapTwins(occupancy, config.twins) if config.twins.enabled else None
        self._odom: np.ndarray | None = None  # the odometry the rivals were last carried to
        self._twin_updates = 0  # localized updates since the twins were last offered
        #: the cells the twins were looked for from since the estimate was last lost or jumped
        self._twin_cells: set[tuple[int, int]] = set()
        #: whether the estimate has been reported localized since it last jumped: a held place is not moved by the
        #: rival check (its margins over 150 scans are not enough to overturn a place the scans confirmed)
        self.held = False
        self._kept = 0  # jumps refused since the held estimate was last reported localized (``keeps``)
        #: ms spent in ``keeps`` and ``check`` since the check was made (a caller times one update by difference)
        self.spent_ms = 0.0

    def reset(self) -> None:
        self.tracker.reset()
        self._odom = None
        self._twin_updates = 0
        self._twin_cells.clear()
        self.held = False
        self._kept = 0

    def after(self, status: str, jumped: bool) -> None:
        """Note the status the filter reported for this update, and whether its estimate jumped."""
        was = self.held
        self.held = (self.held and not jumped and status != "lost") or status == "localized"
        if not was or not self.held or jumped or status == "localized":
            self._kept = 0  # counted anew while the held place is not confirmed again

    @_timed
    def keeps(
        self, filt: Any, held: np.ndarray, new: np.ndarray, odom: np.ndarray, wall_points: np.ndarray | None = None
    ) -> bool:
        """Whether a held estimate at ``held`` stays there instead of jumping to ``new``, the filter's best place
        (``RivalTracker.holds``, with this update's ``wall_points``), at most ``switch_updates`` times before it is
        reported localized again: a filter that goes on leaving it that long is heard, as a rival that leads that
        long takes an estimate not held (a kidnap to a place the scans cannot tell from the held one). If it
        stays, the particles of ``new``'s mode are moved onto ``held``; the rival check then scores ``new`` as
        any other candidate."""
        config = self.tracker.config
        if not (self.held and config.hold) or self._kept >= config.switch_updates:
            return False
        if not self.tracker.holds(held, new, odom, wall_points):
            return False
        self._kept += 1
        assert filt.belief is not None
        move_particles(filt, new, filt.belief.mode_of(new, filt.particles), held)
        return True

    @_timed
    def check(
        self,
        filt: Any,
        odom: np.ndarray,
        pose: np.ndarray | None,
        reading: BeliefReading,
        wall_points: np.ndarray | None,
        left: np.ndarray | None,
        suggestions: np.ndarray,
    ) -> tuple[BeliefReading, np.ndarray | None]:
        """With ``filt`` just weighed and ``odom`` its odometry now: keep this update's wall points, carry and
        re-score the rivals, look at new candidates (the other compact modes, the heaviest particles away from the
        estimate, each fingerprint suggestion at the heading the newest scans fit best and, for a localized
        reading, the map's twins of the place); a
        localized reading with a rival standing becomes ambiguous, and the rivals join the hypotheses. A rival
        that has decisively led an estimate not held since its last jump takes its mode (``move_mode``): the
        second value returned is then the new estimate, else None. When the estimate jumped to another place,
        away from ``left`` (the last estimate, carried to now), the kept scans are dropped, since those before a
        kidnap link to nothing, and ``left`` is held as a rival until the scans since the jump rule it out (it is
        where the robot still is if the jump was wrong). When no place is held (lost), scans and rivals are
        dropped."""
        if self._odom is not None:
            self.tracker.move(self._odom, odom)
        self._odom = odom.copy()
        if reading.status == "lost":
            self._forget_place()
        elif left is not None and pose is not None:
            self._forget_place()
            self.tracker.keep(left)
        if pose is None or filt.belief is None or reading.status == "lost":
            return reading, None
        if wall_points is not None:
            self.tracker.add_scan(odom, np.asarray(wall_points, dtype=float).reshape(-1, 2))
        chosen = reading.chosen
        modes = np.array([m.mean for k, m in enumerate(filt.belief.modes) if k != chosen and m.weight > 0])
        modes = modes.reshape(-1, 3)
        tried = self.tracker.config.candidates  # the heaviest other modes are tried first, whatever their fit
        outside = np.flatnonzero(filt.belief.particle_mode != chosen)
        heaviest = outside[np.argsort(-filt.weights[outside])[: 5 * self.tracker.config.candidates]]
        suggested = self.tracker.headings(np.asarray(suggestions, dtype=float).reshape(-1, 2), odom)
        candidates = np.vstack([modes[tried:], suggested, filt.particles[heaviest]])
        first = modes[:tried]
        if self.twins is not None and reading.status == "localized":
            # the map's look-alikes of a place about to be called localized, and every few updates while it is
            self._twin_updates += 1
            if filt.reading.status != "localized" or self._twin_updates >= self.twins.config.every_updates:
                first = np.vstack([first, self.twins.of(pose)])
                self._twin_updates = 0
                self._twin_cells.add(self.twins.cell_of(pose))
        if self.tracker.update(pose, odom, candidates, first, lead=not self.held) == 0:
            if reading.status == "localized" and not (self.tracker.settled and self.twins_looked()):
                return BeliefReading("ambiguous", reading.covariance, reading.hypotheses, chosen), None
            return reading, None
        decisive = self.tracker.decisive() if self.tracker.config.switch and not self.held else None
        if decisive is not None:
            return self.move_mode(filt, pose, chosen, decisive)
        status = "ambiguous" if reading.status == "localized" else reading.status
        return BeliefReading(status, reading.covariance, reading.hypotheses + self.standing(), chosen), None

    def confirmed(self, confirmation: Confirmation, own: str, checked: str, jumped: bool, switched: bool) -> str:
        """The status to report: the check's reading ``checked`` held back by the filter's ``confirmation``,
        counted on it or, with ``rivals.veto_only``, on the belief's own reading ``own`` (the check then only
        vetoes), a switch to a rival (``switched``) counting the updates that rival led in a row."""
        config = self.tracker.config
        if not config.veto_only:
            return confirmation(checked, jumped)
        status = confirmation(own, jumped, config.switch_updates if switched else 0)
        return checked if checked != "localized" else status

    def _forget_place(self) -> None:
        """The estimate was lost or jumped: drop the kept scans, the rivals and the cells the twins were looked
        for from."""
        self.tracker.reset()
        self._twin_cells.clear()

    def twins_looked(self) -> bool:
        """Whether the map's twins of the place have been looked for from enough cells (``looked_from_cells``)."""
        return self.twins is None or len(self._twin_cells) >= self.twins.config.looked_from_cells

    def standing(self) -> tuple[Hypothesis, ...]:
        """The standing rivals as hypotheses (``rival_hypothesis``)."""
        return tuple(rival_hypothesis(r) for r in self.tracker.rivals)

    def move_mode(self, filt: Any, pose: np.ndarray, chosen: int, rival: int) -> tuple[BeliefReading, np.ndarray]:
        """Move the particles of the estimate's mode (``chosen``; those within 1 m and 30 deg of ``pose`` if it
        is in none) rigidly from ``pose`` to the tracker's ``rival``, which the kept scans favour decisively; the
        place left is held as a rival until they rule it out, and so are the other rivals that stood (the scans
        led by one rival need not rule out the next). Returns the reading there (``ambiguous``) and the place."""
        target = self.tracker.promote(rival)
        self._twin_cells.clear()
        move_particles(filt, pose, chosen, target)
        self.tracker.keep(pose)
        reading = filt.read(target)
        return BeliefReading(
            "ambiguous", reading.covariance, reading.hypotheses + self.standing(), reading.chosen
        ), target


def move_particles(filt: Any, pose: np.ndarray, chosen: int, target: np.ndarray) -> None:
    """Move the particles of mode ``chosen`` (those within 1 m and 30 deg of ``pose`` if it is in none) rigidly
    from ``pose`` to ``target``, and read the filter's belief again."""
    assert filt.belief is not None
    if chosen >= 0:
        members = filt.belief.particle_mode == chosen
    else:
        d = filt.particles - pose
        members = (np.hypot(d[:, 0], d[:, 1]) <= 1.0) & (np.abs(wrap_angle(d[:, 2])) <= np.radians(30.0))
    turn = wrap_angle(target[2] - pose[2])
    c, s = np.cos(turn), np.sin(turn)
    d = filt.particles[members, :2] - pose[:2]
    filt.particles[members, 0] = target[0] + c * d[:, 0] - s * d[:, 1]
    filt.particles[members, 1] = target[1] + s * d[:, 0] + c * d[:, 1]
    filt.particles[members, 2] = wrap_angle(filt.particles[members, 2] + turn)
    filt.belief = read_belief(filt.particles, filt.weights, filt.belief_config)
