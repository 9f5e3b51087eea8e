"""Issue 27, build item 3: each bundled profile's AHRS is the adaptive estimator, `decoupled`
with its defaults, unless the profile says in its file why not.

Two reasons are accepted, each a comment inside the estimator's block of the YAML file
(the block is the estimator's key and the lines indented under it):

- ``# seed port: ...``: a board of the seed's documents that runs the seed's own filter
  (the three seed boards run its Madgwick);
- ``# not decoupled: ...``: a measured reason, which docs/estimators.md must then give with
  its figures.

"Its defaults": a profile's `decoupled` sets nothing but what a board's data dictates, and
the streams already bind the sample period and the limits (docs/estimators.md, "Streams"),
so no setting is allowed: a per-board value would be a fit.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from imuhal.core.samples import GyroSample
from imuhal.plugins.manager import Registry, load_registry
from imuhal.profile.bundled import bundled_profiles
from imuhal.profile.loader import load_profile

PROFILES = sorted(bundled_profiles())
ADAPTIVE = "decoupled"
REASON = re.compile(r"#\s*(seed port|not decoupled):\s*\S")


@pytest.fixture(scope="module")
def registry() -> Registry:
    return load_registry()


def estimator_block(text: str, instance: str) -> str:
    """The lines of ``estimators: {instance: ...}`` in a profile's text, comments included:
    the instance's key line and every line indented deeper than it (or blank) after it."""
    lines = text.splitlines()
    start = lines.index("estimators:")
    key = re.compile(rf"^(\s+){re.escape(instance)}:")
    for i in range(start + 1, len(lines)):
        found = key.match(lines[i])
        if found:
            indent = len(found.group(1))
            block = [lines[i]]
            for line in lines[i + 1:]:
                if line.strip() and len(line) - len(line.lstrip()) <= indent:
                    break
                block.append(line)
            return "\n".join(block)
    raise AssertionError(f"no estimator {instance!r} under estimators:")


def attitude_estimators(path: Path, registry: Registry) -> dict[str, tuple[str, dict]]:
    """instance -> (estimator, settings) of every estimator of the profile that integrates
    the gyro (an AHRS consumes gyro samples; a vario filter does not)."""
    profile = load_profile(path, registry)
    return {name: (cfg.estimator, dict(cfg.settings))
            for name, cfg in profile.estimators.items()
            if GyroSample in registry.estimators.get(cfg.estimator).consumes}


@pytest.mark.parametrize("name", PROFILES)
def test_every_bundled_profile_has_an_ahrs(name: str, registry: Registry) -> None:
    assert attitude_estimators(bundled_profiles()[name], registry)


@pytest.mark.parametrize("name", PROFILES)
def test_the_ahrs_is_decoupled_with_its_defaults_or_the_profile_says_why_not(
        name: str, registry: Registry) -> None:
    path = bundled_profiles()[name]
    text = path.read_text(encoding="utf-8")
    for instance, (estimator, settings) in attitude_estimators(path, registry).items():
        if estimator == ADAPTIVE:
            assert settings == {}, (name, instance, settings)
        else:
            assert REASON.search(estimator_block(text, instance)), (
                f"{name}: {instance} runs {estimator}; make it {ADAPTIVE} or say why in a "
                "'# seed port: ...' or '# not decoupled: ...' comment in its block")


def test_the_gy91_module_is_no_seed_board_and_runs_decoupled(registry: Registry) -> None:
    path = bundled_profiles()["gy91.yaml"]
    assert attitude_estimators(path, registry) == {"ahrs": (ADAPTIVE, {})}
    assert "seed port" not in path.read_text(encoding="utf-8")


def test_a_reason_outside_the_estimators_block_does_not_count() -> None:
    text = ("estimators:\n  ahrs:\n    estimator: madgwick\n  vario:\n"
            "    estimator: vario-kf3  # seed port: the seed's filter\n")
    assert not REASON.search(estimator_block(text, "ahrs"))
    assert REASON.search(estimator_block(text, "vario"))
