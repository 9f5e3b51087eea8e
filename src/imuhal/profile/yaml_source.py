"""Safe YAML loading that remembers where every value came from (line and column).

PyYAML's safe loader is used for scalars; composing the node tree first lets us keep each
node's position, so a validation error on ``devices.imu.settings.odr_hz`` can point at the
exact line. Duplicate mapping keys, which YAML silently collapses, are reported as errors.

Hostile input is bounded: before anything is built, the size the document would have with
every alias (``*name``) expanded is computed on the composed node graph (each shared node
once), and a document expanding to more than ``MAX_VALUES`` values ("billion laughs") or
holding a recursive alias is refused with a located error, in time linear in the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import yaml

Path = tuple[str | int, ...]

MAX_VALUES = 100_000
"""Most values (scalars, mappings, sequences, keys) a profile may expand to; a real board
profile has a few hundred."""


class ExpansionError(yaml.YAMLError):
    """The document is too large once its aliases are expanded, or an alias is recursive."""

    def __init__(self, problem: str, mark: yaml.Mark | None) -> None:
        super().__init__(problem)
        self.problem = problem
        self.problem_mark = mark


@dataclass
class LocatedDocument:
    data: Any
    source: str
    positions: dict[Path, tuple[int, int]] = field(default_factory=dict)
    """Where each value starts."""
    key_positions: dict[Path, tuple[int, int]] = field(default_factory=dict)
    """Where each mapping key starts (for errors about the key itself)."""
    problems: list[str] = field(default_factory=list)

    def where(self, path: Path, *, key: bool = False) -> str:
        """``file:line:column`` of ``path`` (its key with ``key=True``), or of the deepest
        known prefix when the path does not exist in the file (a missing key)."""
        if key and tuple(path) in self.key_positions:
            pos = self.key_positions[tuple(path)]
            return f"{self.source}:{pos[0]}:{pos[1]}"
        for n in range(len(path), -1, -1):
            found = self.positions.get(tuple(path[:n]))
            if found is not None:
                return f"{self.source}:{found[0]}:{found[1]}"
        return self.source


class _Constructor(yaml.SafeLoader):
    pass


MAX_DEPTH = 32
"""Deepest nesting of mappings and sequences read (a board profile nests 6 deep); deeper
documents are refused before PyYAML's recursive composer could exhaust Python's stack."""


def _check_depth(text: str) -> None:
    """Raise ExpansionError at the first collection nested deeper than MAX_DEPTH, from the
    parser's events (an iterative state machine, unlike the composer)."""
    depth = 0
    for event in yaml.parse(text, Loader=yaml.SafeLoader):
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                raise ExpansionError(
                    f"nested more than {MAX_DEPTH} levels deep; a board profile nests a few "
                    "levels - is this the right file?", event.start_mark)  # type: ignore[arg-type]  # PyYAML's C loader has its own Mark class, the same fields as yaml.error.Mark
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1


def load_located(text: str, source: str) -> LocatedDocument:
    """Parse YAML text safely; raise yaml.YAMLError (with its own mark) on syntax errors."""
    _check_depth(text)
    loader = _Constructor(text)
    try:
        node = loader.get_single_node()
    finally:
        loader.dispose()
    doc = LocatedDocument(data=None, source=source)
    if node is None:
        return doc
    _check_expansion(node)
    constructor = yaml.SafeLoader("")
    doc.data = _build(node, (), doc, constructor)
    return doc


def _check_expansion(root: yaml.Node) -> None:
    """Raise ExpansionError when ``root`` expands to more than MAX_VALUES values."""
    sizes: dict[int, int] = {}
    active: set[int] = set()
    # Iterative post-order walk: a deep document must not hit Python's recursion limit.
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        if key in sizes:
            continue
        if isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        else:
            sizes[key] = 1
            continue
        if children_done:
            active.discard(key)
            sizes[key] = 1 + sum(sizes[id(c)] for c in children)
            if sizes[key] > MAX_VALUES:
                raise ExpansionError(
                    f"the document expands to more than {MAX_VALUES} values through its aliases "
                    "(*name); a board profile needs far fewer - write the values out or remove "
                    "the aliases", node.start_mark)
            continue
        if key in active:
            raise ExpansionError("an alias refers to a node that contains it (a recursive "
                                 "alias); a profile must be a tree", node.start_mark)
        active.add(key)
        stack.append((node, True))
        for c in children:
            if id(c) in active:
                raise ExpansionError("an alias refers to a node that contains it (a recursive "
                                     "alias); a profile must be a tree", c.start_mark)
            if id(c) not in sizes:
                stack.append((c, False))


_PLAIN_COLLECTION_TAGS = {"tag:yaml.org,2002:map", "tag:yaml.org,2002:seq",
                          "tag:yaml.org,2002:omap"}
_PLAIN_SCALAR_TAGS = {f"tag:yaml.org,2002:{name}"
                      for name in ("str", "int", "float", "bool", "null")}
"""Scalars a profile holds: text, numbers, booleans and null. ``!!binary`` (bytes),
``!!timestamp`` (dates) and the like name nothing a profile has."""


def _build(node: yaml.Node, path: Path, doc: LocatedDocument, ctor: yaml.SafeLoader) -> Any:
    doc.positions[path] = (node.start_mark.line + 1, node.start_mark.column + 1)
    if isinstance(node, yaml.CollectionNode) and node.tag not in _PLAIN_COLLECTION_TAGS:
        raise yaml.constructor.ConstructorError(
            None, None, f"tag {node.tag!r} is not allowed in a profile (safe YAML only)",
            node.start_mark)
    if isinstance(node, yaml.MappingNode):
        ctor.flatten_mapping(node)
        out: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                raise yaml.constructor.ConstructorError(
                    None, None, "a key must be a plain name or number, not a mapping or a "
                    "list (a complex '? ' key)", key_node.start_mark)
            key = _scalar(key_node, ctor)
            if key in out:
                doc.problems.append(
                    f"{source_pos(doc.source, key_node)}: {_dotted((*path, key))}: "
                    "duplicate key (YAML would silently keep only the last one)"
                )
            child = (*path, key)
            doc.key_positions[child] = (key_node.start_mark.line + 1,
                                        key_node.start_mark.column + 1)
            out[key] = _build(value_node, child, doc, ctor)
        return out
    if isinstance(node, yaml.SequenceNode):
        return [_build(item, (*path, i), doc, ctor) for i, item in enumerate(node.value)]
    return _scalar(node, ctor)


def _scalar(node: yaml.Node, ctor: yaml.SafeLoader) -> Any:
    if node.tag not in _PLAIN_SCALAR_TAGS:
        raise yaml.constructor.ConstructorError(
            None, None, f"tag {node.tag!r} is not allowed in a profile (text, numbers, "
            "true/false and null only)", node.start_mark)
    return ctor.construct_object(node, deep=True)


def source_pos(source: str, node: yaml.Node) -> str:
    return f"{source}:{node.start_mark.line + 1}:{node.start_mark.column + 1}"


def _dotted(path: Path) -> str:
    return ".".join(str(p) for p in path) or "(top level)"


dotted = _dotted
