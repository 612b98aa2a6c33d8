"""A PyYAML safe loader whose constructors fail only with ``yaml.YAMLError`` (bundled into each FMU).

PyYAML's SafeLoader turns a scalar into a value with the constructor of its tag, and for a value that
tag cannot read it raises what Python raises: ``!!int zz`` ValueError, ``!!bool maybe`` KeyError,
``!!timestamp xx`` AttributeError, the date ``2001-13-45`` (a timestamp by its form) ValueError. Every
reader of YAML here (scenarios, --set, comparison and sweep files, rotor files) formats
``yaml.YAMLError`` with the file and line; those others ended in "internal error". :class:`SafeLoader`
raises them as ``yaml.constructor.ConstructorError`` at the value's line instead.
"""

from __future__ import annotations

import yaml

#: what PyYAML's standard constructors raise for a value their tag cannot read
_UNREADABLE = (ValueError, TypeError, KeyError, AttributeError, OverflowError, IndexError)


class SafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` whose unreadable tagged values are ``ConstructorError`` with their mark."""

    def construct_object(self, node, deep=False):
        try:
            return super().construct_object(node, deep=deep)
        except _UNREADABLE as exc:
            self.recursive_objects.pop(node, None)       # left behind by the failed construction
            value = node.value if isinstance(node, yaml.ScalarNode) else f"a {node.id}"
            shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:60] + "..."
            why = f" ({str(exc)[:100]})" if isinstance(exc, ValueError) else ""
            raise yaml.constructor.ConstructorError(
                None, None, f"{shown} is not a valid {node.tag.rsplit(':', 1)[-1]}{why}", node.start_mark) from None
