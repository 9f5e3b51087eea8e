"""The JSON Schema of a board profile, with the settings of every installed plugin.

The profile model (profile/model.py) keeps plugin settings as open mappings because plugins
load later; for editors the schema is built from the registry instead: each bus is one of the
installed bus kinds (chosen by ``kind``), each device one of the installed drivers (chosen by
``driver``) with that driver's Settings, each estimator one of the installed estimators (chosen
by ``estimator``), each ``outputs`` section the installed sink of its name with that sink's
Settings. Unknown keys are rejected everywhere the loader rejects them, so an editor
underlines a typo while it is typed (docs/profiles.md, "Editor support").
"""

from __future__ import annotations

import ast
import inspect
import itertools
import textwrap
from typing import Annotated, Any, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, create_model

from imuhal.drivers.settings import Allowed
from imuhal.plugins.manager import Registry
from imuhal.profile.model import BoardProfile, DeviceConfig, EstimatorConfig, OutputsConfig

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
    return create_model(model.__name__, __base__=model, **overrides)


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
            kind=(Literal[scheme], ...),  # type: ignore[arg-type]  # a model built at run time from the installed plugins: a dynamic Literal or union
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
            driver=(Literal[name], ...),  # type: ignore[arg-type]  # a model built at run time from the installed plugins: a dynamic Literal or union
            settings=(settings, Field(default_factory=settings)),
        ))
    return models  # type: ignore[return-value]  # a model built at run time from the installed plugins: a dynamic Literal or union


def _estimator_models(registry: Registry) -> list[type[BaseModel]]:
    models = []
    for name in registry.estimators.names():
        settings = _with_choices(registry.estimators.get(name).Settings)
        models.append(create_model(
            f"{_ident(name)}Estimator", __base__=EstimatorConfig,
            __doc__=f"An estimator of type {name!r}",
            estimator=(Literal[name], ...),  # type: ignore[arg-type]  # a model built at run time from the installed plugins: a dynamic Literal or union
            settings=(settings, Field(default_factory=settings)),
        ))
    return models  # type: ignore[return-value]  # a model built at run time from the installed plugins: a dynamic Literal or union


class _ClosedOutputs(OutputsConfig):
    """The built-in outputs' sections, and no other key (the installed plugin sinks' are
    added to it by ``_outputs_model``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def _outputs_model(registry: Registry) -> type[BaseModel]:
    """``outputs`` with a section for each installed plugin sink (its Settings), and no
    other key: the loader refuses a section no installed sink takes."""
    fields: dict[str, Any] = {}
    for name in registry.sinks.names():
        if name not in OutputsConfig.model_fields:  # a built-in output, typed already
            settings = _with_choices(registry.sinks.get(name).Settings)
            fields[name.replace("-", "_")] = (settings, Field(default_factory=settings,
                                                              alias=name))
    return create_model("OutputsConfig", __base__=_ClosedOutputs, __doc__=OutputsConfig.__doc__,
                        **fields)


def attribute_docstrings(model: type[BaseModel]) -> dict[str, str]:
    """The docstrings written under fields (``x: int = 0`` then ``\"\"\"units...\"\"\"``),
    from ``model`` and its bases: the project documents settings this way, and editors show
    them as the schema's descriptions."""
    docs: dict[str, str] = {}
    for cls in reversed(model.__mro__):
        if not (isinstance(cls, type) and issubclass(cls, BaseModel)) or cls is BaseModel:
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
        except (OSError, TypeError, SyntaxError):
            continue  # built at run time (create_model) or without source: nothing to add
        body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
        for node, after in itertools.pairwise(body):
            if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and \
                    isinstance(after, ast.Expr) and isinstance(after.value, ast.Constant) and \
                    isinstance(after.value.value, str):
                docs[node.target.id] = inspect.cleandoc(after.value.value)
    return docs


def _describe(schema: dict[str, Any], models: list[type[BaseModel]]) -> None:
    """Add each model's field docstrings to its definition, where pydantic put none."""
    definitions = schema.get("$defs", {})
    for model in models:
        props = definitions.get(model.__name__, {}).get("properties", {})
        for name, doc in attribute_docstrings(model).items():
            if name in props:
                props[name].setdefault("description", doc)


def _settings_models(registry: Registry) -> list[type[BaseModel]]:
    models: list[type[BaseModel]] = [BoardProfile, DeviceConfig, EstimatorConfig]
    models += [registry.buses.get(n).Settings for n in registry.buses.names()]
    models += [registry.drivers.get(n).Settings for n in registry.drivers.names()]
    models += [registry.estimators.get(n).Settings for n in registry.estimators.names()]
    models += [OutputsConfig, *(registry.sinks.get(n).Settings for n in registry.sinks.names())]
    return models


def profile_schema(registry: Registry) -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of a profile for the installed plugins."""
    buses, devices = _bus_models(registry), _device_models(registry)
    estimators = _estimator_models(registry)
    model = create_model(
        "BoardProfile", __base__=BoardProfile, __doc__=BoardProfile.__doc__,
        buses=(dict[str, _union(buses, "kind")], ...),  # type: ignore[arg-type, maybe-unrecognized-str-typeform, misc]  # a model built at run time from the installed plugins: a dynamic Literal or union
        devices=(dict[str, _union(devices, "driver")], ...),  # type: ignore[arg-type, maybe-unrecognized-str-typeform, misc]  # a model built at run time from the installed plugins: a dynamic Literal or union
        estimators=(dict[str, _union(estimators, "estimator")],  # type: ignore[arg-type, maybe-unrecognized-str-typeform, misc]  # a model built at run time from the installed plugins: a dynamic Literal or union
                    Field(default_factory=dict)),
        outputs=(_outputs_model(registry), Field(default_factory=OutputsConfig)),
    )
    schema = model.model_json_schema(mode="validation")
    _describe(schema, [*_settings_models(registry), *buses, *devices, *estimators])
    for name, field_schema in schema.get("properties", {}).items():
        doc = attribute_docstrings(BoardProfile).get(name)
        if doc:
            field_schema.setdefault("description", doc)
    return {"$schema": SCHEMA_DIALECT, "$id": SCHEMA_ID, **schema,
            "title": "imuhal board profile (schema_version 1)"}


def driver_settings_schema(registry: Registry, driver: str) -> dict[str, Any]:
    """The JSON Schema of one driver's ``settings`` mapping."""
    settings = registry.drivers.get(driver).Settings
    schema = _with_choices(settings).model_json_schema()
    for name, doc in attribute_docstrings(settings).items():
        schema.get("properties", {}).get(name, {}).setdefault("description", doc)
    return {"$schema": SCHEMA_DIALECT, **schema, "title": f"settings of the {driver} driver"}
