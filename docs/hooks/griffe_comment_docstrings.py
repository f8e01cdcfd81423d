"""Griffe extension: a module constant's ``#:`` comment lines, just above its assignment, are its docstring.

The code base documents constants the way Sphinx autodoc reads them (``#: text`` above ``NAME = ...``);
griffe reads only a string literal below the assignment. Without this the API pages would leave every such
constant out (mkdocstrings skips objects without a docstring) and links to them could not resolve.
"""

from __future__ import annotations

import ast
import re

import griffe

_COMMENT = re.compile(r"^\s*#:\s?(.*)$")


class CommentDocstrings(griffe.Extension):
    """Give an attribute without a docstring the ``#:`` comment block right above it."""

    def on_attribute_instance(self, *, node, attr, agent, **kwargs):  # noqa: ARG002 (griffe's signature)
        if attr.docstring is not None or not isinstance(node, ast.AST) or not attr.lineno:
            return
        try:
            lines = attr.module.lines
        except Exception:  # noqa: BLE001 (no source: nothing to read)
            return
        found = []
        index = attr.lineno - 2  # the line above the assignment, 0-based
        while index >= 0 and (match := _COMMENT.match(lines[index])):
            found.append(match.group(1))
            index -= 1
        if found:
            found.reverse()
            attr.docstring = griffe.Docstring(
                "\n".join(found), lineno=index + 2, endlineno=attr.lineno - 1, parent=attr
            )
