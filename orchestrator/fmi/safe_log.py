"""The FMU logger callback that formats an FMU's message without trusting it (``safe_logger.c``).

FMI 2.0 hands the master a printf format and its arguments. fmpy's logger proxy passes them to
vsnprintf, so an FMU whose message holds a conversion without its argument crashes the
process that loaded it: a PythonFMU slave raising an exception whose text holds ``%s`` (its C
layer passes the text on as the format, with no arguments) segfaulted ``rotorcosim run``. The
C file next to this module interprets the format one conversion at a time instead, reading
every string the FMU hands over through a pipe (an unreadable address gives EFAULT, not a
crash) and never writing through ``%n`` (its header comment has the rules).

The library is compiled once per source version with the C compiler of the machine (``$CC``,
else cc, gcc or clang) into the per-user cache (``ROTORCOSIM_CACHE`` or ``platformdirs``, folder
``native/``), about 0.2 s, and loaded from there by every process that loads FMUs (the master
and its worker processes). Without a C compiler, or on Windows, fmpy's proxy formats the
messages as before (a build that fails is tried again by the next process an hour later, not by
every worker of a sweep at once: ``native/safe_logger-*.failed`` holds why); ``ROTORCOSIM_SAFE_LOGGER=0``
chooses it on purpose (``1``, the default,
ours; any other value is a SettingError).
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import platform
import shlex
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

log = logging.getLogger(__name__)

SOURCE = Path(__file__).with_name("safe_logger.c")
#: seconds a compilation may take
BUILD_TIMEOUT = 120.0

_TARGET_TYPE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                ctypes.c_char_p)
_lib: ctypes.CDLL | None = None
_tried = False


def cache_root() -> Path:
    """The per-user cache of rotorcosim (``ROTORCOSIM_CACHE`` overrides it)."""
    env = os.environ.get("ROTORCOSIM_CACHE")
    if env:
        return Path(env).expanduser()
    import platformdirs
    return Path(platformdirs.user_cache_dir("rotorcosim"))


def _compiler() -> list[str] | None:
    """``$CC`` (split as a shell would), else the first of cc, gcc, clang on PATH; a SettingError
    when ``$CC`` cannot be split (an unclosed quote)."""
    raw = os.environ.get("CC", "")
    try:
        cc = shlex.split(raw)
    except ValueError as e:          # "No closing quotation": was an internal error of every run
        from orchestrator.untrusted import SettingError
        raise SettingError(f"CC, the C compiler the FMU log formatter is built with (orchestrator/fmi/safe_log.py), "
                           f"cannot be split into words as a shell would ({e}; got {raw!r}); close its quotes, "
                           "or unset CC to use cc, gcc or clang") from None
    if cc:
        found = shutil.which(cc[0])
        return [found, *cc[1:]] if found else None
    for name in ("cc", "gcc", "clang"):
        found = shutil.which(name)
        if found:
            return [found]
    return None


def library_path(cc: list[str]) -> Path:
    """Where the library built from this source with compiler ``cc`` lives."""
    key = hashlib.sha256(SOURCE.read_bytes())
    key.update(f"\0{' '.join(cc)}\0{sys.platform}\0{platform.machine()}".encode())
    return cache_root() / "native" / f"safe_logger-{key.hexdigest()[:16]}.so"


def _ours(path: Path) -> bool:
    """A library file this user owns that nobody else may write (it is loaded as code)."""
    try:
        st = path.stat()
    except OSError:
        return False
    return (stat.S_ISREG(st.st_mode) and st.st_uid == os.getuid()
            and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH))


def _build(cc: list[str], out: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".safe_logger-", suffix=".so", dir=out.parent)
    os.close(fd)
    try:
        done = subprocess.run([*cc, "-O2", "-shared", "-fPIC", "-o", tmp, str(SOURCE)],
                              capture_output=True, text=True, timeout=BUILD_TIMEOUT)
        if done.returncode != 0:
            raise OSError(f"{' '.join(cc)} exited with {done.returncode}: {done.stderr.strip()[-400:]}")
        os.chmod(tmp, 0o755)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


#: seconds after a failed build before the next process tries again (a compiler fixed meanwhile)
RETRY_AFTER = 3600


def _recent(marker: Path) -> bool:
    try:
        import time
        return time.time() - marker.stat().st_mtime < RETRY_AFTER
    except OSError:
        return False


def library() -> ctypes.CDLL | None:
    """The loaded library, built first if needed; None where it cannot be (see the module doc)."""
    global _lib, _tried
    if _tried:
        return _lib
    choice = os.environ.get("ROTORCOSIM_SAFE_LOGGER", "").strip()
    if choice not in ("", "0", "1"):
        from orchestrator.untrusted import SettingError
        raise SettingError(f"ROTORCOSIM_SAFE_LOGGER must be 1 (our logger formats FMU log messages, the "
                           f"default) or 0 (fmpy's proxy does) (got {choice!r}); unset it for the default")
    if choice == "0" or sys.platform == "win32":
        _tried = True
        return None
    cc = _compiler()            # a CC that cannot be split raises, on every call
    _tried = True
    if cc is None:
        log.debug("no C compiler (cc, or $CC): FMU log messages are formatted by fmpy's logger proxy")
        return None
    path = SOURCE
    failed = None
    try:
        path = library_path(cc)
        failed = path.with_suffix(".failed")
        if not _ours(path):
            if _recent(failed):
                # another process failed to build it a moment ago and said why: not every
                # worker process of a sweep compiles and warns again
                log.debug("the FMU logger %s failed to build less than %d s ago (%s): fmpy's proxy formats "
                          "FMU log messages", path, RETRY_AFTER, failed)
                return None
            _build(cc, path)
        if not _ours(path):
            raise OSError(f"{path} is not a file of this user that only it may write")
        lib = ctypes.CDLL(str(path))
    except (OSError, subprocess.SubprocessError) as e:
        log.warning("could not build the FMU logger %s (%s): FMU log messages are formatted by fmpy's "
                    "logger proxy, which an FMU whose message holds %%s or %%n without its argument can crash",
                    path, e)
        if failed is not None:
            try:
                failed.write_text(f"{e}\n")
            except OSError:
                pass
        return None
    lib.rotorcosim_safe_logger.argtypes = [_TARGET_TYPE]
    lib.rotorcosim_safe_logger.restype = ctypes.c_void_p
    lib.rotorcosim_format.restype = ctypes.c_int
    lib.rotorcosim_copy_string.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t,
                                           ctypes.POINTER(ctypes.c_int)]
    lib.rotorcosim_copy_string.restype = ctypes.c_long
    _lib = lib
    return lib


#: longest String value read from an FMU (bytes); a longer one is cut there, with a warning
MAX_STRING_BYTES = 1 << 20
_local = threading.local()


def copy_string(address: int) -> tuple[bytes | None, str]:
    """The bytes of the NUL-terminated string an FMU handed over at ``address`` (fmi2GetString),
    read without trusting the pointer (through a pipe: an unreadable address is EFAULT, not a
    crash), and what went wrong: ``(bytes, "")``; ``(None, "")`` without the library (the caller
    reads the pointer itself, as before); ``(b"", why)`` for an unreadable pointer; the bytes read
    and why when the string was cut (longer than :data:`MAX_STRING_BYTES`, or running into memory
    that cannot be read before its NUL: ``why`` then says how many bytes were kept)."""
    lib = library()
    if lib is None:
        return None, ""
    buf = getattr(_local, "buf", None)
    if buf is None:                 # one buffer per thread (stage threads read at the same time)
        buf = _local.buf = ctypes.create_string_buffer(MAX_STRING_BYTES + 1)
        _local.cut = ctypes.c_int(0)
    cut = _local.cut
    n = lib.rotorcosim_copy_string(address, buf, MAX_STRING_BYTES + 1, ctypes.byref(cut))
    if n == -2:
        return None, ""
    if n < 0:
        return b"", "an address that cannot be read"
    data = ctypes.string_at(buf, n)         # n bytes (buf.raw would copy the whole MiB first)
    if cut.value:
        return data, (f"a string that runs into memory that cannot be read before its end (no NUL "
                      f"byte; {n} bytes kept, cut there)")
    if n >= MAX_STRING_BYTES:
        return data, f"a string longer than {MAX_STRING_BYTES} bytes (cut there)"
    return data, ""


def safe_logger(target) -> int | None:
    """The address of the C logger that formats each message and calls ``target`` (a ctypes
    callback of fmpy's ``fmi2CallbackLoggerTYPE``, kept alive by the caller) with it; None
    when the library is not available. One target per process (the C side keeps one)."""
    lib = library()
    if lib is None:
        return None
    return lib.rotorcosim_safe_logger(ctypes.cast(target, _TARGET_TYPE))
