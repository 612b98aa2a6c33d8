"""Which FMI call each FMU in the master's process is in: readable after the process died.

An FMU loaded into the master's process (``isolation: none``) that crashes takes the process
with it: no exception, no final summary.json. So that the run folder still tells where it
died, :class:`CallRecord` keeps, for every FMU instance, the FMI function it is in now and the
simulation time, in a small memory-mapped file of the run folder (``.rotorcosim.calls``,
made and removed by :class:`orchestrator.coupling.lifecycle.RunFolder`). The kernel keeps a
shared mapping's writes when the process dies, whatever kills it, so the file outlives a crash;
a run that ends in order removes it. :func:`read_calls` reads it back: a function still
recorded there never returned.

Layout: a JSON head (``instances``, ``calls_at``: the record's offset, a multiple of
:data:`ALIGN`), then ``2 n`` doubles, for instance ``k`` the function code (0: in no call;
``i + 1``: :data:`FUNCTIONS` ``[i]``) and the time [s] (NaN before the first step). The cost
is three stores per call (about 55 ns) (the calls of the stepping loop are a few per FMU and macro step).
"""

from __future__ import annotations

import contextlib
import json
import math
import mmap
import os
import stat

import numpy as np

FUNCTIONS = ("fmi2Instantiate", "fmi2SetupExperiment", "fmi2EnterInitializationMode",
             "fmi2ExitInitializationMode", "fmi2SetReal", "fmi2GetReal", "fmi2DoStep",
             "fmi2SetInteger", "fmi2GetInteger", "fmi2SetBoolean", "fmi2GetBoolean", "fmi2SetString",
             "fmi2GetString", "fmi2SetRealInputDerivatives", "fmi2GetFMUstate", "fmi2SetFMUstate",
             "fmi2FreeFMUstate", "fmi2GetBooleanStatus", "fmi2Terminate", "fmi2FreeInstance")
CODE = {name: float(i + 1) for i, name in enumerate(FUNCTIONS)}
SLOT_BYTES = 16
ALIGN = 4096           # the record starts at a multiple of this, after the JSON head


class CallRecord:
    """The shared record of FMU instances ``names`` in a new file ``path`` (a JSON head with the
    names and the record's offset, then the record). :meth:`slot` gives an instance's
    ``(array, index)`` for :class:`orchestrator.fmi.subsystem.Subsystem`. :meth:`remove`
    unlinks the file when the run ends in order (the mapping stays valid for adapters that
    still hold a slot: the file keeps its size until the last one lets go)."""

    def __init__(self, path, names, head: dict | None = None):
        self.path = path
        self.names = list(names)
        n = max(len(self.names), 1)
        text = json.dumps({**(head or {}), "instances": self.names, "calls_at": 0}).encode()
        self.offset = (len(text) + 64) // ALIGN * ALIGN + ALIGN
        text = json.dumps({**(head or {}), "instances": self.names, "calls_at": self.offset}).encode()
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), 0o644)
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise OSError(f"{path} is not a regular file")
            os.ftruncate(fd, self.offset + SLOT_BYTES * n)
            os.pwrite(fd, text, 0)
            self._map = mmap.mmap(fd, self.offset + SLOT_BYTES * n, flags=mmap.MAP_SHARED,
                                  prot=mmap.PROT_READ | mmap.PROT_WRITE)
        finally:
            os.close(fd)
        # a memoryview of doubles: a store costs about half of a numpy item store (~20 ns)
        self.slots = memoryview(self._map)[self.offset:self.offset + SLOT_BYTES * n].cast("d")

    def slot(self, name: str) -> tuple[memoryview, int] | None:
        try:
            return self.slots, 2 * self.names.index(name)
        except ValueError:
            return None

    def remove(self) -> None:
        """The run ended in order: no call to tell about."""
        for k in range(len(self.slots)):
            self.slots[k] = 0.0
        with contextlib.suppress(OSError):
            os.unlink(self.path)


def read_calls(path) -> list[tuple[str, str, float]]:
    """``(instance, FMI function, t)`` of every call recorded as open in the record file ``path``
    (a missing, large, short or odd file gives what it holds, or nothing)."""
    from orchestrator.untrusted import InputError, read_bytes
    try:                                # bounded: 256 instances need far less than 1 MiB
        raw = read_bytes(path, what="FMI call record", limit=1 << 20)
        head = json.loads(raw.split(b"\0", 1)[0].decode() or "{}")
    except (InputError, ValueError, RecursionError):   # "[[[[..." in a crafted record: nested too deeply
        return []
    names = head.get("instances") if isinstance(head, dict) else None
    offset = head.get("calls_at") if isinstance(head, dict) else None
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names) and isinstance(offset, int)
            and ALIGN <= offset < len(raw)):
        return []
    data = raw[offset:offset + SLOT_BYTES * len(names)]
    vals = np.frombuffer(data[: len(data) // 8 * 8], dtype=np.float64)
    out = []
    for k, name in enumerate(names):
        if 2 * k + 1 >= vals.size:
            break
        code, t = vals[2 * k], vals[2 * k + 1]
        if math.isfinite(code) and code == int(code) and 1 <= code <= len(FUNCTIONS):
            out.append((name, FUNCTIONS[int(code) - 1], float(t)))
    return out


def describe_calls(calls) -> str:
    """``'bearing1' in fmi2DoStep at t=0.004 s`` for each open call, joined by "; "."""
    return "; ".join(f"'{n}' in {f}" + (f" at t={t:.12g} s" if math.isfinite(t) else "") for n, f, t in calls)
