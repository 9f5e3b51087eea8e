"""Where the bundled board profiles live (profiles/ in the source tree, installed with the
package as imuhal/profiles)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

DEFAULT_PROFILE = "seed-paraglider-vario.yaml"


def bundled_profiles() -> dict[str, Path]:
    """Bundled profile file names -> paths."""
    root = Path(str(files("imuhal") / "profiles"))
    return {p.name: p for p in sorted(root.glob("*.yaml"))}


def default_profile_path() -> Path:
    return Path(str(files("imuhal") / "profiles" / DEFAULT_PROFILE))
