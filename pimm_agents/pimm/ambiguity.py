"""Whether the estimate is the only place the scans allow: the ambiguity check that sits beside PIMM's filter.

After each measurement update the localizer hands the check the filter's belief (read-only, ``BeliefView``) and
the reading of the estimate; the check keeps the recent scans and the look-alike places they cannot rule out
(rivals.py) and returns a ``Decision``: the status it allows (a localized reading with a rival standing becomes
``ambiguous``), the rivals to report as hypotheses, and, when a rival has decisively led an estimate not held
since its last jump, the place to move the estimate's mode to. Candidates are the filter's other modes, its best
particles away from the estimate, the fingerprint suggestions and, for a localized reading, the map's own twins
of the place (pimm_env/mapping/twins.py). Before the filter's estimate jumps away from a held place, ``holds``
says whether the kept scans keep it there. The localizer applies both through the filter's public methods;
the check never writes the filter. Whether the estimate is held is the check's own state: ``after`` is told each
update's reported status.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.localizer import Hypothesis
from pimm_agents.particles.belief import BeliefReading, BeliefView
from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.pimm.rivals import CANDIDATES, RivalConfig, RivalTracker
from pimm_agents.pimm.twin_queue import TwinQueue
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.mapping.twins import MapTwins, TwinConfig

#: The map's twins are offered when an estimate is about to be called localized, and again at this many updates'
#: interval while it is (2 s of 10 Hz scans): a twin the scans had ruled out is not re-offered at once (ours).
TWINS_EVERY_UPDATES = 20
#: A place is called localized only once its twins have been looked for from this many map cells: a search from
#: one cell can miss a twin that the next cell's finds (measured: docs/design.md#the-maps-twins).
TWINS_FROM_CELLS = 2
#: the map's twins that match the place's walls best, tried whatever the scans say of them (the rest are looked
#: at in turns, twin_queue.py)
TWINS_BY_WALLS = 6


def rival_hypothesis(place: np.ndarray) -> Hypothesis:
    """A rival place as a hypothesis: weight 0 (the filter holds no particles there), 0.5 m and 10 deg (1 sigma)."""
    return Hypothesis(
        float(place[0]), float(place[1]), float(place[2]), 0.0, np.diag([0.25, 0.25, np.radians(10.0) ** 2])
    )


@dataclass(frozen=True)
class Decision:
    """What the check allows after one measurement update: the ``status`` (the reading's, or ``ambiguous``),
    ``rivals`` to report beside the belief's hypotheses, and ``move_to``: a place the estimate's mode moves to
    (None: it stays)."""

    status: str
    rivals: tuple[Hypothesis, ...] = ()
    move_to: np.ndarray | None = None
    led: int = 0  # with ``move_to``: the updates in a row the rival led (they count towards its confirmation)


class AmbiguityCheck:
    """The rival check beside one filter: ``review`` after each measurement update, ``holds`` before a held
    estimate jumps, ``after`` with the status reported. It keeps its own state (the rivals, the map's twins,
    whether the estimate is held) and returns decisions; it never writes the filter."""

    def __init__(
        self,
        occupancy: OccupancyGrid,
        wall_field: LikelihoodField,
        temperature: float,
        config: RivalConfig,
        twins: MapTwins | None = None,
    ) -> None:
        #: look-alike places the recent scans cannot tell from the estimate (rivals.py)
        self.tracker = RivalTracker(wall_field, occupancy.free, temperature, config)
        #: the map's twins (``twins``: with the world's table of them loaded, so no update works one out)
        self.twins = twins if twins is not None else MapTwins(occupancy, TwinConfig())
        self._odom: np.ndarray | None = None  # the odometry the rivals were last carried to
        self._twin_updates = 0  # localized updates since the twins were last offered
        #: the cells the twins were looked for from since the estimate was last lost or jumped
        self._twin_cells: set[tuple[int, int]] = set()
        #: every twin of the place since it was last estimated after a jump, looked at in turns
        self.queue = TwinQueue()
        #: whether the estimate has been reported localized since it last jumped: a held place is not moved by the
        #: rival check (its margins over 150 scans are not enough to overturn a place the scans confirmed)
        self.held = False
        self._kept = 0  # jumps refused since the held estimate was last reported localized (``holds``)

    def reset(self) -> None:
        self.tracker.reset()
        self._odom = None
        self._twin_updates = 0
        self._twin_cells.clear()
        self.queue.clear()
        self.held = False
        self._kept = 0

    def after(self, status: str, jumped: bool) -> None:
        """Note the status reported for this update, and whether the estimate jumped."""
        was = self.held
        self.held = (self.held and not jumped and status != "lost") or status == "localized"
        if not was or not self.held or jumped or status == "localized":
            self._kept = 0  # counted anew while the held place is not confirmed again

    def holds(self, held: np.ndarray, new: np.ndarray, odom: np.ndarray, wall_points: np.ndarray | None) -> bool:
        """Whether a held estimate at ``held`` stays there instead of jumping to ``new``, the filter's best place
        (``RivalTracker.holds``, with this update's ``wall_points``), at most ``switch_updates`` times before it is
        reported localized again: a filter that goes on leaving it that long is heard, as a rival that leads that
        long takes an estimate not held (a kidnap to a place the scans cannot tell from the held one). If it
        stays, the localizer moves the particles of ``new``'s mode onto ``held``; ``review`` then scores ``new``
        as any other candidate."""
        config = self.tracker.config
        if not self.held or self._kept >= config.switch_updates:
            return False
        if not self.tracker.holds(held, new, odom, wall_points):
            return False
        self._kept += 1
        return True

    def review(
        self,
        view: BeliefView,
        odom: np.ndarray,
        pose: np.ndarray | None,
        reading: BeliefReading,
        reported: str,
        wall_points: np.ndarray | None,
        left: np.ndarray | None,
        suggestions: np.ndarray,
    ) -> Decision:
        """With the filter's belief ``view`` just weighed, ``odom`` the odometry now and ``reported`` the status
        reported at the last update: keep this update's wall points, carry and re-score the rivals, look at new
        candidates (the other compact modes, the heaviest particles away from the estimate, each fingerprint
        suggestion at the heading the newest scans fit best and, for a localized reading, the map's twins of the
        place). A localized reading with a rival standing becomes ambiguous, and the rivals are reported. A rival
        that has decisively led an estimate not held since its last jump takes its mode (``move_to``). When the
        estimate jumped to another place, away from ``left`` (the last estimate, carried to now), the kept scans
        are dropped, since those before a kidnap link to nothing, and ``left`` is held as a rival until the scans
        since the jump rule it out (it is where the robot still is if the jump was wrong). When no place is held
        (lost), scans and rivals are dropped."""
        unchanged = Decision(reading.status)
        if self._odom is not None:
            self.tracker.move(self._odom, odom)
            self.queue.move(self._odom, odom)
        self._odom = odom.copy()
        if reading.status == "lost":
            self._forget_place()
        elif left is not None and pose is not None:
            self._forget_place()
            self.tracker.keep(left)
        if pose is None or reading.status == "lost":
            return unchanged
        if wall_points is not None:
            self.tracker.add_scan(odom, np.asarray(wall_points, dtype=float).reshape(-1, 2))
        chosen, belief = reading.chosen, view.belief
        modes = np.array([m.mean for k, m in enumerate(belief.modes) if k != chosen and m.weight > 0])
        modes = modes.reshape(-1, 3)
        tried = CANDIDATES  # the heaviest other modes are tried first, whatever their fit
        outside = np.flatnonzero(belief.particle_mode != chosen)
        heaviest = outside[np.argsort(-view.weights[outside])[: 5 * CANDIDATES]]
        suggested = self.tracker.headings(np.asarray(suggestions, dtype=float).reshape(-1, 2), odom)
        candidates = np.vstack([modes[tried:], suggested, view.particles[heaviest]])
        first = modes[:tried]
        if reading.status == "localized":
            # the map's look-alikes of a place about to be called localized, and every few updates while it is
            self._twin_updates += 1
            if reported != "localized" or self._twin_updates >= TWINS_EVERY_UPDATES:
                twins = self.twins.of(pose)
                first = np.vstack([first, twins[:TWINS_BY_WALLS]])
                self._twin_updates = 0
                self._twin_cells.add(self.twins.cell_of(pose))
                if not self.queue.started and self.tracker.settled:
                    self.queue.start(twins, self.tracker, odom)
        if self.queue.started and self.tracker.settled:
            first = np.vstack([first, self.queue.take(self.tracker, odom)])
        if self.tracker.update(pose, odom, candidates, first, lead=not self.held) == 0:
            if reading.status == "localized" and not (self.tracker.settled and self.twins_looked()):
                return Decision("ambiguous")
            return unchanged
        decisive = None if self.held else self.tracker.decisive()
        if decisive is not None:
            return self._move(pose, decisive)
        status = "ambiguous" if reading.status == "localized" else reading.status
        return Decision(status, self.standing())

    def _forget_place(self) -> None:
        """The estimate was lost or jumped: drop the kept scans, the rivals and the cells the twins were looked
        for from."""
        self.tracker.reset()
        self._twin_cells.clear()
        self.queue.clear()

    def twins_looked(self) -> bool:
        """Whether the map's twins of the place have been looked for from enough cells (``TWINS_FROM_CELLS``) and
        every one of them has been looked at (``TwinQueue.examined``)."""
        return len(self._twin_cells) >= TWINS_FROM_CELLS and self.queue.examined

    def standing(self) -> tuple[Hypothesis, ...]:
        """The standing rivals as hypotheses (``rival_hypothesis``)."""
        return tuple(rival_hypothesis(r) for r in self.tracker.rivals)

    def _move(self, pose: np.ndarray, rival: int) -> Decision:
        """The estimate's mode moves from ``pose`` to the tracker's ``rival``, which the kept scans favour
        decisively; the place left is held as a rival until they rule it out, and so are the other rivals that
        stood (the scans led by one rival need not rule out the next). The reading there is ``ambiguous``."""
        target = self.tracker.promote(rival)
        self._twin_cells.clear()
        self.queue.clear()
        self.tracker.keep(pose)
        return Decision("ambiguous", self.standing(), target, self.tracker.config.switch_updates)
