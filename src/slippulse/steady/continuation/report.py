"""What a continuation run did: :class:`FamilyReport`."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class FamilyReport:
    """What a continuation run did."""

    written: list = field(default_factory=list)      # labels written this run
    resumed_from: str | None = None
    failures: list = field(default_factory=list)     # (tau_d_ratio, message), every failed solve
    attempts: int = 0                                # solves attempted this run (failed included)
    reached: float = float("nan")                    # farthest τ_d/τ_min converged (direction)
    reached_beta: float = float("nan")               # β and L of that pulse
    reached_L: float = float("nan")
    stopped_early: bool = False
    stop_reason: str = ""                            # why the run stopped before `stop`
    hint: str = ""                                   # what would take it further
    wall_time: float = 0.0
    resumed_method: str = ""                         # how the pulse resumed from was computed
    resumed_previous: tuple | None = None            # (β, q, L) of the arclength pulse above it
    resumed_held: bool = False                       # that pulse's march had ds held (hold)
    resumed_cap: float = float("nan")                # and its cap on ds (cap_shrink)
    checks: int = 0                                  # grid checks
    failed_checks: list = field(default_factory=list)  # (tau_d_ratio, message): written failed
    deep_steps: int = 0                              # accepted steps of the deep march
    limit_reached: bool = False                      # stopped cleanly at max_length
    strategy: str = ""                               # the deep driver's combination (printed)
    direction: int = -1                              # −1: τ_d continued downward, +1: upward

    def record(self, tau_d_ratio, ok, message):
        """Count one attempted solve; a failed one is kept with its τ_d/τ_min and message."""
        self.attempts += 1
        if not ok:
            self.failures.append((float(tau_d_ratio), message))

    def wrote(self, pulse):
        """A converged pulse was written: the run has reached its τ_d (the farthest in its
        direction)."""
        self.written.append(pulse.label)
        # NaN-safe: the first, or one farther along
        if not (self.direction * (self.reached - pulse.tau_d_ratio) >= 0):
            self.reached, self.reached_beta, self.reached_L = pulse.tau_d_ratio, pulse.beta, pulse.L

    def stop(self, reason, hint):
        self.stopped_early, self.stop_reason, self.hint = True, reason, hint

