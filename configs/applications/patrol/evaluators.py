"""The patrol application's sensory evaluators: `patrol/wall_in_range` (border protection is
applicable once a wall is within reach) and `patrol/report_due` (a report is due when nobody has
published one for Report/period seconds)."""

from __future__ import annotations

from mrta_zenoh.messages import PointCloud
from mrta_agent.runtime.plugins import AgentContext, SensoryEvaluator

from .keys import ALL_REPORTS
from .layers import BorderParams, ReportParams, SonarView
from .messages import Report



class WallInRange(SensoryEvaluator):
    """Applicable while the sonar is fresh and some echo is within BorderProtection/wall_range."""

    sections = {"BorderProtection": BorderParams}

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        self.range = ctx.section("BorderProtection", BorderParams).wall_range

    def is_applicable(self, now: float) -> bool:
        for s in self.sensors:
            if not s.is_up_to_date(now):
                return False
            if isinstance(s.latest, PointCloud):
                view = SonarView(s.latest)
                if any(r <= self.range for _, _, r, _ in view.points):
                    return True
        return False


class ReportDue(SensoryEvaluator):
    """Applicable while sensors are fresh and no robot has reported for `Report/period` seconds."""

    sections = {"Report": ReportParams}

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        self.period = ctx.section("Report", ReportParams).period
        self.last_report: float | None = None
        self.subscribe(ALL_REPORTS, self._on_report, msg_type=Report)

    def _on_report(self, sample) -> None:
        # the report's own stamp (the reporter's clock): on simulation time, exact whatever
        # the network's delay, which keeps lockstep runs reproducible
        self.last_report = sample.message.header.stamp

    def is_applicable(self, now: float) -> bool:
        if not all(s.is_up_to_date(now) for s in self.sensors):
            return False
        return self.last_report is None or now - self.last_report >= self.period
