"""``--set key.path=value`` overrides: surgery on the YAML node tree before the sections are read.

An override's nodes are marked with their origin (``--set k=v``) so that problems
with them are reported against the command line, not a line of the file.
"""

from __future__ import annotations

import yaml

from orchestrator.scenario.model import CHILD_SCHEMA, SECTION_KEYS, SetOrigin
from orchestrator.scenario.nodes import MAP_TAG, STR_TAG, NodeReader, YamlLoader, did_you_mean, unshared
from orchestrator.untrusted import InputError, compose_yaml


# -- overrides ---------------------------------------------------------
def apply_override(reader: NodeReader, root, text: str) -> None:
    """Apply one ``--set key.path=value`` to the node tree (before validation).

    Length: one walk down the node tree, with the message for each way a path can be wrong
    (syntax, unknown key, index out of range, aliased node, type of the value) where it is met."""
    origin = SetOrigin(f"--set {text}")      # the caller's value (export-ssp carries its file from anywhere)
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key:
        reader.problems.append(f"{origin}: expected KEY.PATH=VALUE (got {text!r}); "
                             "e.g. --set coupling.macro_step=5e-5")
        return
    if any(not part.strip() for part in key.split(".")):
        reader.problems.append(f"{origin}: the key path {key!r} has an empty part (a leading, trailing or "
                               "double '.'); write its parts with single dots between them, "
                               "e.g. --set coupling.macro_step=5e-5")
        return
    try:
        vnode = compose_yaml(raw.strip(), display=origin, loader_cls=YamlLoader)
    except InputError as exc:                        # bounded like the file: depth, aliases, digits
        reader.problems.append(str(exc))
        return
    except yaml.YAMLError as exc:
        reader.problems.append(f"{origin}: the value is not valid YAML ({exc}); quote or fix it")
        return
    if vnode is None:
        vnode = yaml.ScalarNode("tag:yaml.org,2002:null", "")
    reader.mark(vnode, origin)
    if not isinstance(root, yaml.MappingNode):
        return                                       # the file itself is broken (reported)
    node, schema, done, parts = root, "top", [], key.split(".")
    while parts:
        part = ".".join(parts) if schema == "params" else parts[0]   # names may hold dots
        parts = [] if schema == "params" else parts[1:]
        here = ".".join(done) or "top level"
        nxt = CHILD_SCHEMA.get((schema, part), CHILD_SCHEMA.get(schema, "leaf"))
        if parts and nxt == "leaf":
            reader.problems.append(f"{origin}: '{'.'.join(done + [part])}' is a single value, not a section; "
                                 f"use --set {'.'.join(done + [part])}=VALUE")
            return
        if isinstance(node, yaml.SequenceNode):
            if not part.isdigit() or int(part) >= len(node.value):
                reader.problems.append(f"{origin}: '{here}' has entries 0..{len(node.value) - 1} (got "
                                     f"{part!r}); use an index, e.g. --set {here}.0.gain=2")
                return
            if not parts:
                node.value[int(part)] = vnode
                return
            child = node.value[int(part)] = unshared(node.value[int(part)])
        elif isinstance(node, yaml.MappingNode):
            entries = {str(reader.value(k)): i for i, (k, _) in enumerate(node.value)
                       if isinstance(k, yaml.ScalarNode)}
            allowed = tuple(entries) if schema == "instances" else SECTION_KEYS.get(schema)
            if allowed is not None and part not in allowed:
                what = "instance" if schema == "instances" else "key"
                reader.problems.append(f"{origin}: unknown {what} '{part}' in '{here}'; "
                                     f"{did_you_mean(part, allowed)}valid: {', '.join(allowed) or '(none)'}")
                return
            if not parts:
                if part in entries:
                    i = entries[part]
                    node.value[i] = (node.value[i][0], vnode)
                else:
                    knode = yaml.ScalarNode(STR_TAG, part)
                    reader.mark(knode, origin)
                    node.value.append((knode, vnode))
                return
            if part in entries:                      # copy: an alias (*anchor) must not change too
                knode, child = node.value[entries[part]]
                child = unshared(child)
                node.value[entries[part]] = (knode, child)
            else:                                    # a section not written in the file
                knode, child = yaml.ScalarNode(STR_TAG, part), yaml.MappingNode(MAP_TAG, [])
                reader.mark(knode, origin)
                reader.mark(child, origin)
                node.value.append((knode, child))
        else:
            reader.problems.append(f"{origin}: '{here}' is a single value, not a section; "
                                 f"use --set {here}=VALUE")
            return
        node, schema, done = child, nxt, done + [part]
