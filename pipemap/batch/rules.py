"""The decision rules a batch scores its runs by: each is ``pipemap score`` with flags.

A SPEC's ``rule`` key names one of :data:`RULES`; a run is replayed and scored with
the localizer that ``pipemap score`` builds from the rule's flags (a test checks each
against the command line), so that every table can say exactly which rule made it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pipemap.localizer import LocalizerConfig

__all__ = ["RULES", "Rule"]


@dataclass(frozen=True)
class Rule:
    """A decision rule of the replayed localizer: a name, the ``pipemap score`` flags
    that select it, and what it does."""

    name: str
    flags: tuple[str, ...]
    description: str
    distinct_consecutive: bool = True
    two_view: bool = True
    verify: bool = True
    #: The paper's rule (:meth:`localizer.LocalizerConfig.paper_rule`), which turns
    #: every check of pipemap's off.
    paper: bool = False

    def config(self, threshold: float) -> LocalizerConfig:
        """The localizer's settings of ``pipemap score FLAGS --threshold threshold``."""
        from pipemap.localizer import LocalizerConfig

        config = LocalizerConfig(
            threshold=threshold,
            distinct_consecutive=self.distinct_consecutive,
            two_view=self.two_view,
            verify=self.verify,
        )
        return config.paper_rule() if self.paper else config

    def command(self) -> str:
        """``pipemap score`` with this rule's flags, as a user would type it."""
        return " ".join(("pipemap score", *self.flags))


#: Every rule a SPEC may name. A test checks each against the command line's flags.
RULES: dict[str, Rule] = {
    rule.name: rule
    for rule in (
        Rule(
            "default",
            (),
            "the two-view check decides known or new, the similarity "
            "ranks the candidates and calls for probes, a visit is never the junction it "
            "just left",
        ),
        Rule(
            "paper",
            ("--rule", "paper"),
            "the paper's Algorithm 1: the similarity threshold decides, every known "
            "junction competes (the previous visit's too), the rotation is the NCC peak "
            "shift's; none of pipemap's checks (two-view, ports, odometry)",
            paper=True,
        ),
        Rule(
            "no-verify",
            ("--no-verify",),
            "the similarity threshold decides; the two-view rotation; a visit is never "
            "the junction it just left",
            verify=False,
        ),
        Rule(
            "no-two-view",
            ("--no-two-view",),
            "the similarity threshold decides, the NCC rotation; a visit is never the "
            "junction it just left",
            two_view=False,
            verify=False,
        ),
    )
}
