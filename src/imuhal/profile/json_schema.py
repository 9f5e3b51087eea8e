"""The JSON Schema of a board profile, with the settings of every installed plugin.

The profile model (profile/model.py) keeps plugin settings as open mappings because plugins
load later; for editors the schema is built from the registry instead: each bus is one of the
installed bus kinds (chosen by ``kind``), each device one of the installed drivers (chosen by
``driver``) with that driver's Settings, each estimator one of the installed estimators (chosen
by ``estimator``). Unknown keys are rejected everywhere the loader rejects them, so an editor
underlines a typo while it is typed (docs/profiles.md, "Editor support").
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, create_model

from imuhal.drivers.settings import Allowed
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile, DeviceConfig, EstimatorConfig

SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
SCHEMA_ID = "https://imuhal.invalid/schemas/profile-v1.json"


def _ident(name: str) -> str:
    return "".join(part.capitalize() for part in name.replace("-", "_").split("_"))


def _with_choices(model: type[BaseModel]) -> type[BaseModel]:
    """``model`` with each table-backed field's allowed values as a JSON Schema ``enum``."""
    overrides: dict[str, Any] = {}
    for name, info in model.model_fields.items():
        allowed = next((m for m in info.metadata if isinstance(m, Allowed)), None)
        if allowed is None:
            continue
        extra = dict(info.json_schema_extra or {}) if isinstance(info.json_schema_extra,
                                                                  dict) else {}
        extra["enum"] = list(allowed.values)
        overrides[name] = (info.annotation, Field(info.default, description=info.description,
                                                  json_schema_extra=extra))
    if not overrides:
        return model
    return create_model(model.__name__, __base__=model, **overrides)  # type: ignore[call-overload]


def _union(members: list[Any], discriminator: str) -> Any:
    if len(members) == 1:
        return members[0]
    return Annotated[Union[tuple(members)], Field(discriminator=discriminator)]  # noqa: UP007


def _bus_models(registry: Registry) -> list[type[BaseModel]]:
    models = []
    for scheme in registry.buses.names():
        factory = registry.buses.get(scheme)
        models.append(create_model(
            f"{_ident(scheme)}Bus", __base__=_with_choices(factory.Settings),
            __doc__=f"A bus of kind {scheme!r}: {factory.description}",
            kind=(Literal[scheme], ...),  # type: ignore[valid-type]
        ))
    return models


def _device_models(registry: Registry) -> list[type[BaseModel]]:
    models = []
    for name in registry.drivers.names():
        driver = registry.drivers.get(name)
        settings = _with_choices(driver.Settings)
        models.append(create_model(
            f"{_ident(name)}Device", __base__=DeviceConfig,
            __doc__=f"A device driven by {name!r}" + (f": {driver.description}"
                                                      if getattr(driver, "description", "")
                                                      else ""),
            driver=(Literal[name], ...),  # type: ignore[valid-type]
            settings=(settings, Field(default_factory=settings)),
        ))
    return models


def _estimator_models(registry: Registry) -> list[type[BaseModel]]:
    models = []
    for name in registry.estimators.names():
        settings = _with_choices(registry.estimators.get(name).Settings)
        models.append(create_model(
            f"{_ident(name)}Estimator", __base__=EstimatorConfig,
            __doc__=f"An estimator of type {name!r}",
            estimator=(Literal[name], ...),  # type: ignore[valid-type]
            settings=(settings, Field(default_factory=settings)),
        ))
    return models


def profile_schema(registry: Registry) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a profile for the installed plugins."""
    strict = ConfigDict(extra="forbid", frozen=True)
    model = create_model(
        "BoardProfile", __base__=BoardProfile, __doc__=BoardProfile.__doc__,
        buses=(dict[str, _union(_bus_models(registry), "kind")], ...),  # type: ignore[misc]
        devices=(dict[str, _union(_device_models(registry), "driver")], ...),  # type: ignore[misc]
        estimators=(dict[str, _union(_estimator_models(registry), "estimator")],  # type: ignore[misc]
                    Field(default_factory=dict)),
    )
    model.model_config = {**model.model_config, **strict}
    schema = model.model_json_schema(mode="validation")
    return {"$schema": SCHEMA_DIALECT, "$id": SCHEMA_ID, **schema,
            "title": "imuhal board profile (schema_version 1)"}


def driver_settings_schema(registry: Registry, driver: str) -> dict[str, Any]:
    """The JSON Schema of one driver's ``settings`` mapping."""
    schema = _with_choices(registry.drivers.get(driver).Settings).model_json_schema()
    return {"$schema": SCHEMA_DIALECT, **schema, "title": f"settings of the {driver} driver"}
