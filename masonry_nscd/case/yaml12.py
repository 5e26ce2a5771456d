"""YAML 1.2 for case files: a core-schema reader on top of PyYAML, and the writer of scalars that read back the same with YAML 1.1 and 1.2."""

from __future__ import annotations

import math
import re
from typing import Any, ClassVar

import yaml
from pydantic import BaseModel

from masonry_nscd.case.errors import CaseError

_TAG = "tag:yaml.org,2002:"

_RESOLVERS_1_2: list[tuple[str, re.Pattern[str], list[str | None]]] = [
    (_TAG + "null", re.compile(r"^(?:~|null|Null|NULL|)$"), ["~", "n", "N", ""]),
    (_TAG + "bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")),
    (
        _TAG + "int",
        re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"),
        list("-+0123456789"),
    ),
    (
        _TAG + "float",
        re.compile(
            r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
            r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
        ),
        list("-+0123456789."),
    ),
    (_TAG + "merge", re.compile(r"^(?:<<)$"), ["<"]),
]


class _CaseLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the YAML 1.2 core schema for plain scalars and with duplicate
    keys refused."""

    yaml_implicit_resolvers: ClassVar[dict] = {}  # filled below, not inherited (YAML 1.1)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, yaml.Node] = {}
            for key_node, _ in node.value:
                if key_node.tag == _TAG + "merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping",
                        node.start_mark,
                        "found a key that is not a scalar (a list or a mapping)",
                        key_node.start_mark,
                    ) from None
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping",
                        node.start_mark,
                        f"found duplicate key {key!r}",
                        key_node.start_mark,
                    )
                seen[key] = key_node
        return super().construct_mapping(node, deep=deep)


def _clip(text: str, size: int = 40) -> str:
    return repr(text) if len(text) <= size else repr(text[: size - 3] + "...")


def _construct_int(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    text = str(loader.construct_scalar(node)).strip()
    try:
        if text.lower().startswith("0o"):
            return int(text, 0)
        if text.lower().startswith("0x"):
            return int(text, 0)
        return int(text, 10)
    except ValueError:
        raise yaml.constructor.ConstructorError(
            None, None, f"{_clip(text)} is not an integer", node.start_mark
        ) from None


def _construct_float(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> float:
    text = str(loader.construct_scalar(node)).strip()
    low = text.lower()
    if low in (".inf", "+.inf"):
        return math.inf
    if low == "-.inf":
        return -math.inf
    if low == ".nan":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise yaml.constructor.ConstructorError(
            None, None, f"{_clip(text)} is not a number", node.start_mark
        ) from None


def _construct_bool(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> bool:
    text = str(loader.construct_scalar(node)).strip().lower()
    if text in ("true", "false"):
        return text == "true"
    raise yaml.constructor.ConstructorError(
        None, None, f"{_clip(text)} is not true or false", node.start_mark
    )


for _tag, _regexp, _first in _RESOLVERS_1_2:
    _CaseLoader.add_implicit_resolver(_tag, _regexp, _first)
_CaseLoader.add_constructor(_TAG + "int", _construct_int)
_CaseLoader.add_constructor(_TAG + "float", _construct_float)
_CaseLoader.add_constructor(_TAG + "bool", _construct_bool)


class _CaseDumper(yaml.SafeDumper):
    """A dumper that quotes every string that either YAML 1.1 or YAML 1.2 would read as
    something else than a string, so that the output reads back the same with both."""

    yaml_implicit_resolvers: ClassVar[dict] = {}


for _first_char, _resolvers in yaml.SafeDumper.yaml_implicit_resolvers.items():
    _CaseDumper.yaml_implicit_resolvers[_first_char] = list(_resolvers)
for _tag, _regexp, _first in _RESOLVERS_1_2:
    _CaseDumper.add_implicit_resolver(_tag, _regexp, _first)


def read_yaml(text: str, source: str = "<text>") -> Any:
    """Parse YAML text as case files are read (YAML 1.2 core schema: ``0.3e6`` is a float,
    duplicate keys refused). Any problem becomes a :class:`CaseError` naming ``source`` and,
    for syntax errors, the line and column."""
    try:
        return yaml.load(text, Loader=_CaseLoader)  # a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        kind = "error" if isinstance(exc, yaml.constructor.ConstructorError) else "syntax error"
        what = str(exc.problem or exc.context or "invalid YAML")
        if exc.problem and exc.context:
            cmark = exc.context_mark
            what += f" ({exc.context}" + (f" at line {cmark.line + 1})" if cmark else ")")
        raise CaseError(f"{source}: YAML {kind}{where}: {what}") from None
    except yaml.YAMLError as exc:
        raise CaseError(f"{source}: cannot read the YAML: {exc}") from None
    except RecursionError:
        raise CaseError(f"{source}: the YAML is nested too deeply") from None
    except (ValueError, TypeError, AttributeError, OverflowError) as exc:
        # PyYAML's own constructors (e.g. !!timestamp with a bad value) can raise these
        raise CaseError(f"{source}: cannot read the YAML: {exc}") from None


def _format_float(x: float) -> str:
    """The shortest text that reads back as the same float in YAML 1.1 and 1.2."""
    if math.isnan(x):
        return ".nan"
    if math.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    if x == 0.0 or 1e-3 <= abs(x) < 1e4:
        text = repr(x)
        if "e" not in text:
            return text
    for digits in range(18):
        text = f"{x:.{digits}e}"
        if float(text) == x:
            break
    mantissa, exponent = text.split("e")
    if "." not in mantissa:
        mantissa += ".0"
    sign = exponent[0]
    return f"{mantissa}e{sign}{exponent[1:].lstrip('0') or '0'}"


def _reads_back(text: str, value: Any) -> bool:
    """Whether ``text`` reads back as ``value`` with this module's reader and with PyYAML's."""
    try:
        return read_yaml(text) == value and yaml.safe_load(text) == value
    except (CaseError, yaml.YAMLError):
        return False


def format_scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _format_float(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(format_scalar(v) for v in value) + "]"
    if isinstance(value, BaseModel):  # in a list (openings, pattern courses): a flow mapping
        quiet = getattr(type(value), "OMIT_NULL", ())  # null there: "the case's", left out
        return "{" + ", ".join(f"{k}: {format_scalar(getattr(value, k))}"
                               for k in type(value).model_fields
                               if not (k in quiet and getattr(value, k) is None)) + "}"
    text = yaml.dump(
        value, Dumper=_CaseDumper, width=float("inf"), allow_unicode=True, explicit_end=False
    )
    text = text.removesuffix("\n").removesuffix("\n...").removesuffix("...")
    if "\n" in text or not _reads_back(text, value):
        text = yaml.dump(
            value, Dumper=_CaseDumper, width=float("inf"), allow_unicode=True, default_style='"'
        ).strip()
    return text
