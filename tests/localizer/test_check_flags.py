"""Each of pipemap's checks answers to its own flag only: ``--allow-repeat``,
``--no-verify``, ``--no-two-view`` (which implies ``--no-verify``), ``--no-port-check``
and ``--no-odometry-check`` each turn off their own check and leave every other one
acting. The settings come from the command line as ``pipemap replay`` and ``score``
build them (:func:`pipemap.cli.replay_commands.localizer_config`)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipemap.cli.localizer_options import apply_presets
from pipemap.cli.parser import build_parser
from pipemap.cli.replay_commands import localizer_config
from pipemap.localizer import Localizer, LocalizerConfig
from tests.localizer.junctions import CORNER_EXITS, TEE_EXITS, junction
from tests.localizer.test_paper_rule import _look_alike

#: For each check, a tour that it alone decides: (sweep, exits, dead reckoning,
#: odometer) per visit. The last visit is junction 0 again (or its look-alike), and
#: every other check would call it known.
WITNESS = {
    # The same sweep and exits, 12 m from where junction 0 was.
    "odometry_check": (
        (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
        (junction(1), CORNER_EXITS, (3.0, 0.0), 3.0),
        (junction(0), TEE_EXITS, (9.0, 9.0), 6.0),
    ),
    # The same sweep where it was, with two exits where junction 0 has three ports.
    "port_check": (
        (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
        (junction(1), CORNER_EXITS, (3.0, 0.0), 3.0),
        (junction(0), CORNER_EXITS, (0.0, 0.0), 6.0),
    ),
    # The same sweep at once, no pipe driven.
    "distinct_consecutive": (
        (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
        (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
    ),
    # Junction 0's look-alike where junction 0 was, with its exits: the similarity
    # passes the threshold, the keypoints do not fit.
    "verify": (
        (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
        (junction(1), CORNER_EXITS, (3.0, 0.0), 3.0),
        (_look_alike(0, 7), TEE_EXITS, (0.0, 0.0), 6.0),
    ),
}

#: Each flag, the settings it turns off.
FLAGS = {
    "--allow-repeat": {"distinct_consecutive"},
    "--no-verify": {"verify"},
    "--no-two-view": {"two_view", "verify"},
    "--no-port-check": {"port_check"},
    "--no-odometry-check": {"odometry_check"},
}


def _config(*flags: str) -> LocalizerConfig:
    args = build_parser().parse_args(["replay", "run.mcap", *flags])
    apply_presets(args)
    config = localizer_config(args)
    assert isinstance(config, LocalizerConfig)
    return config


def _last_known(config: LocalizerConfig, check: str) -> bool:
    """Whether the last visit of ``check``'s tour is called known (junction 0)."""
    loc = Localizer(config)
    decisions = [
        loc.localize(s, exits_rad=e, position_m=p, odometer_m=o) for s, e, p, o in WITNESS[check]
    ]
    last = decisions[-1]
    assert not last.known or last.node == 0
    return last.known


@pytest.mark.parametrize("check", sorted(WITNESS))
def test_each_tour_is_decided_by_its_check_alone(check: str) -> None:
    # At the defaults the check calls the last visit new; with it alone off, known.
    assert not _last_known(LocalizerConfig(), check)
    assert _last_known(replace(LocalizerConfig(), **{check: False}), check)


def test_each_flag_sets_exactly_its_own_settings() -> None:
    defaults = LocalizerConfig()
    for flag, off in FLAGS.items():
        config = _config(flag)
        changed = {name for name in WITNESS if getattr(config, name) != getattr(defaults, name)}
        changed |= {"two_view"} if config.two_view != defaults.two_view else set()
        assert changed == off, flag
        assert not any(getattr(config, name) for name in off), flag


@pytest.mark.parametrize("flag", sorted(FLAGS))
@pytest.mark.parametrize("check", sorted(WITNESS))
def test_a_flag_turns_off_its_own_check_and_no_other(flag: str, check: str) -> None:
    config = _config(flag)
    if check in FLAGS[flag]:
        # The flag's own check: the tour it alone decided now calls the visit known.
        assert _last_known(config, check)
    else:
        # Any other check still acts under the flag: it keeps the visit new, and the
        # visit is known once that check too is off.
        assert not _last_known(config, check)
        assert _last_known(replace(config, **{check: False}), check)
