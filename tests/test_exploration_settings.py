"""The exploration-families benchmark's --info-gain FIELD=VALUE overrides: numbers for real fields of the policy,
a usage error for anything else; --oracle-noise HIT,FALSE_ALARM: two shares in order
(benchmarks/exploration_families.py)."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from exploration_families import parse_noise, parse_settings  # noqa: E402

from palpate.core.planning.info_gain import InfoGain  # noqa: E402


def test_fields_become_numbers_that_replace_the_policys():
    got = parse_settings(argparse.ArgumentParser(), ["entropy_weight=4", "spread_stride=2", "correlation_mm=2.5e1"])
    assert got == {"entropy_weight": 4, "spread_stride": 2, "correlation_mm": 25.0}
    policy = dataclasses.replace(InfoGain(memory=None), **got)
    assert (policy.entropy_weight, policy.spread_stride, policy.correlation_mm) == (4, 2, 25.0)


@pytest.mark.parametrize("item", ["bogus=1", "entropy_weight", "objective=entropy", "memory=1",
                                  "entropy_weight=four"])
def test_anything_else_is_a_usage_error(item, capsys):
    with pytest.raises(SystemExit):
        parse_settings(argparse.ArgumentParser(prog="exploration_families.py"), [item])
    assert "--info-gain" in capsys.readouterr().err


def test_oracle_noise_is_two_ordered_shares(capsys):
    assert parse_noise(argparse.ArgumentParser(), "0.8,0.1") == (0.8, 0.1)
    for bad in ("0.1,0.8", "1.2,0", "0.5", "a,b", "0.5,-0.1"):
        with pytest.raises(SystemExit):
            parse_noise(argparse.ArgumentParser(prog="exploration_families.py"), bad)
        assert "--oracle-noise" in capsys.readouterr().err
