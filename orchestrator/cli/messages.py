"""What the command line prints when a verb fails: one line that names the failure and its fix
(:func:`_describe`), and warnings as one line each (:func:`_clean_warnings`)."""

from __future__ import annotations

import errno as _errno
import warnings

from orchestrator.errors import CosimError


#: what to do about the operating system's errors that bad paths give (``--out`` a file, a
#: folder without write permission, ...), added to their one-line message
_OS_FIXES = {
    _errno.EEXIST: "a file of that name is in the way where a folder is needed: remove it or choose another name",
    _errno.ENOTDIR: "a part of that path is a file, not a folder: choose another path",
    _errno.EISDIR: "that is a folder where a file is needed: choose a file name",
    _errno.ENOENT: "no such file or folder: check the path (relative paths start in the current folder)",
    _errno.EACCES: "permission denied: choose a place you can write to, or change its permissions",
    _errno.EPERM: "operation not permitted: choose a place you own",
    _errno.EROFS: "that file system is read-only: choose another place",
    _errno.ENOSPC: "the disk is full: free some space or choose another place",
    _errno.EDQUOT: "your disk quota is used up: free some of it or choose another place",
    _errno.ENAMETOOLONG: "the name is too long: choose a shorter one",
}


def _memory_limit() -> str:
    """'this process may use at most N MiB of memory (`ulimit -v`)' when such a limit is set, else ''."""
    try:
        import resource
        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    except (ImportError, OSError, ValueError):     # pragma: no cover - not POSIX
        return ""
    if soft == resource.RLIM_INFINITY:
        return ""
    return f"this process may use at most {soft / 2**20:.0f} MiB of memory (`ulimit -v`): raise that limit"


def _describe(exc: BaseException) -> str:
    if isinstance(exc, CosimError):
        return f"error: {exc}"
    if isinstance(exc, MemoryError):
        # was "internal error: MemoryError ... this is a bug in rotorcosim"
        limit = _memory_limit()
        return ("error: out of memory" + (f" ({exc})" if str(exc) else "") + "; "
                + (limit if limit else "free memory (close other programs) or run a smaller case (a coarser "
                   "film grid, fewer recorded signals)"))
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if exc.filename else ""
        fix = _OS_FIXES.get(exc.errno, "")
        limit = _memory_limit()
        if not fix and limit and any(w in str(exc) for w in ("shared object", "map segment", "allocate memory")):
            # a library that cannot be mapped under a memory limit: llvmlite says "Could not find/load
            # shared object file 'libllvmlite.so' ... cannot be found, or the permissions are incorrect"
            fix = f"if the file is there, {limit}"
        return f"error: {where}{exc.strerror or exc}" + (f"; {fix}" if fix else "")
    import yaml
    if isinstance(exc, yaml.YAMLError):
        return f"error: malformed YAML: {exc}"
    return (f"internal error: {type(exc).__name__}: {exc}\n"
            f"(this is a bug in rotorcosim: rerun with --debug for the traceback and report it)")


def _clean_warnings(debug: bool):
    """Format warnings as one line, ``warning: message`` (with ``--debug``: also where from);
    returns the previous ``warnings.formatwarning``. (Only the format is replaced, so
    recording warnings, as ``pytest.warns`` does, still works.)"""
    from orchestrator.untrusted import terminal_text

    def one_line(message, category, filename, lineno, line=None):
        # warnings quote files and FMUs (a summary.json, a signal name): nothing in them drives the terminal
        text = terminal_text(" ".join(str(message).split()))
        where = f" ({filename}:{lineno}, {category.__name__})" if debug else ""
        return f"warning: {text}{where}\n"

    previous = warnings.formatwarning
    warnings.formatwarning = one_line
    return previous
