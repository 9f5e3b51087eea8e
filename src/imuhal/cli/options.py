"""Validated command options: a command's parsed arguments as a frozen pydantic model whose
flag-combination rules are data (``Needs``), each mistake one line naming the option and the
fix (``ImuhalError``: exit 2). argparse still parses each value (its types give the per-value
messages); the model checks how the values go together."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator

from imuhal.core.errors import ImuhalError

OptionsT = TypeVar("OptionsT", bound="CommandOptions")


@dataclass(frozen=True)
class Needs:
    """A flag-combination rule: when ``given`` holds of the options, ``needs`` must hold too,
    or the command stops with ``message`` (a string, or a function of the options for one
    that quotes a value)."""

    given: Callable[[Any], bool]
    needs: Callable[[Any], bool]
    message: str | Callable[[Any], str]

    def violated(self, options: Any) -> str | None:
        """The rule's message when ``options`` break it, else None."""
        if not self.given(options) or self.needs(options):
            return None
        return self.message(options) if callable(self.message) else self.message


class CommandOptions(BaseModel):
    """Base of a command's options: the fields are the argparse destinations the command
    reads (others, such as ``func``, are ignored); ``RULES`` are checked in order and the
    first broken one is the error."""

    model_config = ConfigDict(frozen=True, arbitrary_types_allowed=True, extra="ignore")

    RULES: ClassVar[tuple[Needs, ...]] = ()
    ERROR: ClassVar[type[ImuhalError]] = ImuhalError
    """The error class a broken rule raises (a command may have its own subclass)."""

    @model_validator(mode="after")
    def _combinations(self) -> CommandOptions:
        for rule in self.RULES:
            message = rule.violated(self)
            if message is not None:
                raise ValueError(message)
        return self

    @classmethod
    def from_args(cls: type[OptionsT], args: argparse.Namespace) -> OptionsT:
        """The options of ``args``, or the first broken rule as a one-line ``ERROR``."""
        try:
            return cls.model_validate(vars(args))
        except ValidationError as exc:
            first = exc.errors(include_url=False)[0]
            if first["loc"]:
                # A field error is a bug between the parser and the model (argparse has
                # typed every value): an internal error, not the user's mistake.
                raise
            raise cls.ERROR(first["msg"].removeprefix("Value error, ")) from None
