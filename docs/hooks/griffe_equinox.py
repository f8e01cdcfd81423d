"""Griffe extension: an Equinox module's ``__init__``, as the dataclass Equinox makes of it.

``eqx.Module`` subclasses are dataclasses made by a metaclass, which griffe cannot see (its dataclass
support reads the ``@dataclass`` decorator), so their pages would show a class without parameters and an
``Args:`` section naming none of them. For each class under ``equinox.Module`` without an ``__init__`` of its
own or inherited, this adds the one the dataclass has: the annotated fields of the class and its bases, in
field order, with ``eqx.field``'s ``default``/``default_factory`` and without ``init=False`` fields or
``ClassVar``/``AbstractVar`` declarations.
"""

from __future__ import annotations

import griffe

_MODULE_BASES = {"equinox.Module", "equinox._module.Module", "eqx.Module"}
_FIELD_CALLS = {"equinox.field", "equinox._module.field", "dataclasses.field", "eqx.field"}
_NOT_FIELDS = ("AbstractVar", "AbstractClassVar", "ClassVar", "InitVar")


def _is_equinox(cls, seen=None) -> bool:
    seen = set() if seen is None else seen
    if cls.path in seen:
        return False
    seen.add(cls.path)
    for base in cls.bases:
        if (base if isinstance(base, str) else base.canonical_path) in _MODULE_BASES:
            return True
    try:
        bases = cls.resolved_bases
    except Exception:  # noqa: BLE001 (an unresolvable base: not ours to judge)
        return False
    return any(_is_equinox(base, seen) for base in bases if base.is_class)


def _mro(cls):
    try:
        return [cls, *cls.mro()]
    except Exception:  # noqa: BLE001
        return [cls]


def _field_call(attr):
    value = attr.value
    if isinstance(value, griffe.ExprCall) and str(value.function.canonical_path) in _FIELD_CALLS:
        return {arg.name: arg.value for arg in value.arguments if isinstance(arg, griffe.ExprKeyword)}
    return None


def _parameters(cls) -> list[griffe.Parameter]:
    params: dict[str, griffe.Parameter] = {}
    for klass in reversed(_mro(cls)):
        for member in klass.members.values():
            if member.is_alias or not member.is_attribute or member.annotation is None:
                continue
            if "property" in member.labels or (
                "class-attribute" in member.labels and "instance-attribute" not in member.labels
            ):
                continue
            if str(member.annotation).split("[", 1)[0].rsplit(".", 1)[-1] in _NOT_FIELDS:
                continue
            args = _field_call(member)
            if args is not None and str(args.get("init", "")) == "False":
                continue
            if args is None:
                default = member.value
            elif "default_factory" in args:
                default = griffe.ExprCall(function=args["default_factory"], arguments=[])
            else:
                default = args.get("default")
            params[member.name] = griffe.Parameter(
                member.name,
                annotation=member.annotation,
                kind=griffe.ParameterKind.positional_or_keyword,
                default=default,
                docstring=member.docstring,
            )
    return list(params.values())


def _own_init(klass) -> bool:
    """Whether a class defines ``__init__`` in its source (not one this extension made)."""
    init = klass.members.get("__init__")
    return init is not None and not (
        not init.is_alias and init.extra.get("griffe_equinox", {}).get("generated")
    )


def _apply(obj, done: set[str]) -> None:
    for member in list(obj.members.values()):
        if member.is_alias or member.path in done:
            continue
        done.add(member.path)
        if member.is_module:
            _apply(member, done)
        elif member.is_class:
            if not any(_own_init(klass) for klass in _mro(member)) and _is_equinox(member):
                init = griffe.Function(
                    "__init__",
                    lineno=0,
                    endlineno=0,
                    parent=member,
                    parameters=griffe.Parameters(
                        griffe.Parameter("self", kind=griffe.ParameterKind.positional_or_keyword),
                        *_parameters(member),
                    ),
                    returns="None",
                )
                init.extra["griffe_equinox"]["generated"] = True
                member.set_member("__init__", init)
                member.labels.add("dataclass")
            _apply(member, done)


class EquinoxInit(griffe.Extension):
    """Give each Equinox module the ``__init__`` its dataclass has."""

    def on_package(self, *, pkg, **kwargs):  # noqa: ARG002 (griffe's signature)
        _apply(pkg, set())
