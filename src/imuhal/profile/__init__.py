"""Board profiles: pydantic models of a board, loaded from YAML with located errors."""

from imuhal.profile.loader import check_profile, load_profile
from imuhal.profile.model import BoardProfile

__all__ = ["BoardProfile", "check_profile", "load_profile"]
