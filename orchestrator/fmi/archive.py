"""Read FMU archives as untrusted input.

An FMU is a zip file from anyone. Before anything in it is used this module
checks the archive and parses ``modelDescription.xml`` safely:

* member names: no absolute paths, no drive letters, no backslashes, no ``..``
  components, no NUL, no duplicates;
* no symbolic links or other special files;
* no encrypted members, and only the compression methods Python reads (stored,
  deflate, bzip2, lzma; not deflate64 or the AES of WinZip);
* the file itself: a regular file (no FIFO or device), opened once;
* sizes: each member at most :data:`MAX_MEMBER_BYTES`, all members together at
  most :data:`MAX_TOTAL_BYTES`, at most :data:`MAX_MEMBERS` members, no member
  larger than :data:`RATIO_CHECK_MIN_BYTES` whose compression ratio exceeds
  :data:`MAX_COMPRESSION_RATIO`, and no archive of more than
  :data:`ARCHIVE_RATIO_MIN_BYTES` whose members together exceed
  :data:`MAX_ARCHIVE_RATIO` (zip bombs of many small members); sizes are
  enforced while extracting too, so a lying header does not help, and a
  caller may pass a smaller budget (a run's total, see
  :mod:`orchestrator.fmi.extraction`); a member whose CRC fails (a corrupted
  download) is reported as such;
* ``modelDescription.xml``: a file member of at most :data:`MAX_XML_BYTES`,
  parsed by :func:`orchestrator.fmi.model_description.parse_model_description`
  (its rules are there; :class:`ModelDescription`, :class:`Variable` and the
  parser are re-exported here).

Every problem raises :class:`orchestrator.errors.FmuError` naming the file,
what is wrong and how to fix it.

The limits are module constants read at call time (tests monkeypatch them).
"""

from __future__ import annotations

import functools
import os
import stat
import sys
import zipfile
import zlib
from pathlib import Path, PurePosixPath

from orchestrator import read_log
from orchestrator.errors import FmuError
from orchestrator.fmi.model_description import ModelDescription, Variable, _fail, parse_model_description
from orchestrator.untrusted import InputError, open_regular

__all__ = ["check_archive", "safe_extract", "read_model_description", "cached_model_description",
           "binary_path", "platform_dir", "ModelDescription", "Variable", "parse_model_description"]

MAX_MEMBER_BYTES = 512 * 2**20        # one member, uncompressed
MAX_TOTAL_BYTES = 2 * 2**30           # all members, uncompressed
MAX_MEMBERS = 20000
MAX_XML_BYTES = 32 * 2**20            # modelDescription.xml (read from the archive with this limit)
MAX_COMPRESSION_RATIO = 1000.0        # uncompressed / compressed, for members above:
RATIO_CHECK_MIN_BYTES = 1 * 2**20
MAX_ARCHIVE_RATIO = 100.0             # all members together, for archives above:
ARCHIVE_RATIO_MIN_BYTES = 32 * 2**20

_CHUNK = 1 << 20


class _OwnedZip(zipfile.ZipFile):
    """A ZipFile over a file object it owns (closed with the archive)."""

    def close(self) -> None:
        fp = self.fp
        try:
            super().close()
        finally:
            if fp is not None:
                fp.close()


def _open_zip(path: Path) -> zipfile.ZipFile:
    path = Path(path)
    if not path.exists():
        raise _fail(path, "FMU file not found", "check the path (relative paths in a scenario are relative to the YAML file)")
    if path.is_dir():
        raise _fail(path, "is a directory, expected an .fmu (zip) file", "point to the .fmu file itself")
    try:
        f = open_regular(path, what="FMU file")      # no FIFO, no device: they would hang or never end
    except InputError as e:
        raise FmuError(str(e)) from None
    try:
        return _OwnedZip(f)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError) as e:
        f.close()
        raise _fail(path, f"not a valid zip archive ({e})", "rebuild or re-export the FMU") from None
    except OSError as e:
        f.close()
        raise _fail(path, f"cannot be read ({e})", "check permissions and that the file is complete") from None


def _corrupt(path: Path, name: str, exc: Exception) -> FmuError:
    return _fail(path, f"member {name!r} is corrupt ({exc})", "the file is damaged (an interrupted or corrupted "
                 "download produces this): download or build the FMU again")


def _check_name(path: Path, name: str) -> PurePosixPath:
    bad = None
    if not name or "\x00" in name:
        bad = "an empty name or a NUL character"
    elif "\\" in name:
        bad = "a backslash (Windows path separator)"
    elif name.startswith("/"):
        bad = "an absolute path"
    elif len(name) >= 2 and name[1] == ":":
        bad = "a drive letter"
    else:
        parts = PurePosixPath(name).parts
        if ".." in parts:
            bad = "a '..' component (path traversal)"
    if bad:
        raise _fail(path, f"unsafe member name {name!r} in the archive: it has {bad}",
                    "do not use this FMU; ask its author to rebuild it with plain relative member names")
    return PurePosixPath(name)


_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate", zipfile.ZIP_BZIP2: "bzip2",
            zipfile.ZIP_LZMA: "lzma"}


def check_archive(path: Path | str, *, required: str = "modelDescription.xml") -> list[zipfile.ZipInfo]:
    """Check every member header of the FMU at ``path``; return the member list.

    Raises :class:`FmuError` for unsafe names, links, too many or too large
    members, or absurd compression ratios.
    """
    path = Path(path)
    with _open_zip(path) as zf:
        infos = zf.infolist()
    if len(infos) > MAX_MEMBERS:
        raise _fail(path, f"has {len(infos)} members (limit {MAX_MEMBERS})",
                    "this is not a plausible FMU; raise orchestrator.fmi.archive.MAX_MEMBERS if you trust it")
    seen: dict[tuple[str, ...], str] = {}
    total = 0
    for info in infos:
        name = info.filename
        # by the path it is extracted to: 'a//b' and 'a/./b' are 'a/b' (the later one replaced the earlier)
        key = _check_name(path, name).parts
        if not key:          # '.', './': the extraction folder itself (IsADirectoryError naming a temporary folder)
            raise _fail(path, f"member {name!r} names no file (the archive's top folder itself)",
                        "the archive is malformed: export or zip it again")
        if key in seen:
            twice = "" if seen[key] == name else f" (as {seen[key]!r} and {name!r})"
            raise _fail(path, f"member {name!r} appears twice in the archive{twice}", "rebuild the FMU")
        seen[key] = name
        mode = info.external_attr >> 16
        ftype = stat.S_IFMT(mode)
        if ftype and ftype not in (stat.S_IFREG, stat.S_IFDIR):
            kind = "a symbolic link" if stat.S_ISLNK(mode) else "a special file"
            raise _fail(path, f"member {name!r} is {kind}",
                        "FMUs must contain regular files only; ask the author to rebuild it without links")
        if info.flag_bits & 0x1:
            raise _fail(path, f"member {name!r} is encrypted",
                        "FMUs are not encrypted; export or zip it again without a password")
        if info.compress_type not in _METHODS:
            raise _fail(path, f"member {name!r} is compressed with zip method {info.compress_type}, which rotorcosim "
                        f"cannot read (it reads {', '.join(_METHODS.values())})",
                        "zip the FMU again with deflate (e.g. `zip -r` or Python's zipfile)")
        if info.file_size > MAX_MEMBER_BYTES:
            raise _fail(path, f"member {name!r} is {info.file_size} bytes uncompressed (limit {MAX_MEMBER_BYTES})",
                        "raise orchestrator.fmi.archive.MAX_MEMBER_BYTES if you trust this FMU")
        if (info.file_size > RATIO_CHECK_MIN_BYTES
                and info.file_size > MAX_COMPRESSION_RATIO * max(info.compress_size, 1)):
            ratio = info.file_size / max(info.compress_size, 1)
            raise _fail(path, f"member {name!r} has compression ratio {ratio:.0f} (limit {MAX_COMPRESSION_RATIO:.0f}); "
                        "this looks like a zip bomb", "do not use this FMU")
        total += info.file_size
        if total > MAX_TOTAL_BYTES:
            raise _fail(path, f"members add up to more than {MAX_TOTAL_BYTES} bytes uncompressed",
                        "raise orchestrator.fmi.archive.MAX_TOTAL_BYTES if you trust this FMU")
    _file_in_the_way(path, infos, seen)
    if total > ARCHIVE_RATIO_MIN_BYTES:
        packed = max(sum(i.compress_size for i in infos), 1)
        if total > MAX_ARCHIVE_RATIO * packed:
            raise _fail(path, f"has compression ratio {total / packed:.0f} over the whole archive ({total} bytes "
                        f"from {packed}; limit {MAX_ARCHIVE_RATIO:.0f} above {ARCHIVE_RATIO_MIN_BYTES} bytes): this "
                        "looks like a zip bomb", "do not use this FMU (or raise "
                        "orchestrator.fmi.archive.MAX_ARCHIVE_RATIO if you trust it)")
    md = [i for i in infos if i.filename.rstrip("/") == required]
    if not md:
        raise _fail(path, f"has no {required} at the top level of the archive",
                    "this is not an FMU; export it again as an FMI 2.0 co-simulation FMU" if required ==
                    "modelDescription.xml" else "export it again")
    if md[0].is_dir():
        raise _fail(path, f"has a folder named {required}/, not a file",
                    "this is not a valid archive; export it again")
    return infos


def _file_in_the_way(path: Path, infos: list[zipfile.ZipInfo], seen: dict[tuple[str, ...], str]) -> None:
    """A file member that another member needs as its folder ('zz' and 'zz/y'): extracting both
    failed with the OS's "File exists" / "Is a directory" naming a temporary folder and advising to
    remove a file there. ``seen``: each member's path parts -> its name."""
    folders = {k[:i]: name for k, name in seen.items() for i in range(1, len(k))}
    for info in infos:
        key = PurePosixPath(info.filename).parts
        if not info.is_dir() and key in folders:
            raise _fail(path, f"member {info.filename!r} is a file, and member {folders[key]!r} needs it as its "
                        "folder", "the archive is malformed: export or zip it again")


def _read_member(zf: zipfile.ZipFile, path: Path, info: zipfile.ZipInfo, limit: int) -> bytes:
    chunks = []
    n = 0
    for b in _chunks(zf, info, path):
        n += len(b)
        if n > limit:
            raise _fail(path, f"member {info.filename!r} is larger than {limit} bytes when decompressed "
                        "(its header says less)", "do not use this FMU")
        chunks.append(b)
    return b"".join(chunks)


def _chunks(zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path):
    """The decompressed bytes of member ``info`` in chunks; a CRC or stream failure is an
    FmuError saying the member is corrupt."""
    with zf.open(info) as f:
        while True:
            try:
                b = f.read(_CHUNK)
            except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as e:
                raise _corrupt(path, info.filename, e) from None
            if not b:
                return
            yield b


def safe_extract(path: Path | str, dest: Path | str, *, budget: int | None = None,
                 required: str = "modelDescription.xml") -> Path:
    """Extract the FMU at ``path`` into directory ``dest`` after :func:`check_archive`.

    Sizes are re-checked while decompressing; ``budget`` (bytes) lowers the
    total limit (a run's remaining extraction budget). Returns ``dest`` as a Path.
    """
    path = Path(path)
    dest = Path(dest)
    infos = check_archive(path, required=required)
    limit = MAX_TOTAL_BYTES if budget is None else min(budget, MAX_TOTAL_BYTES)
    declared = sum(i.file_size for i in infos)
    if declared > limit:
        raise _fail(path, f"members add up to {declared} bytes uncompressed, more than the run's extraction "
                    f"budget ({limit} bytes left)", "use fewer or smaller FMUs in one run (or raise "
                    "orchestrator.fmi.extraction.MAX_RUN_EXTRACT_BYTES)")
    dest.mkdir(parents=True, exist_ok=True)
    root = dest.resolve()
    total = 0
    with _open_zip(path) as zf:
        for info in infos:
            rel = PurePosixPath(info.filename)
            target = (root / Path(*rel.parts)).resolve() if rel.parts else root
            if target != root and root not in target.parents:
                raise _fail(path, f"member {info.filename!r} would be written outside {root}", "do not use this FMU")
            if info.is_dir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            total += _copy_member(zf, info, target, path, limit - total, limit)
            mode = (info.external_attr >> 16) & 0o777
            if mode & 0o100:
                os.chmod(target, 0o755)
    return dest


def _copy_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, target: Path, path: Path, left: int,
                 limit: int) -> int:
    """Decompress one member into ``target`` (at most MAX_MEMBER_BYTES and ``left`` bytes);
    return the bytes written. A member that fails (CRC, size) leaves no file behind."""
    n = 0
    try:
        with open(target, "wb") as out:
            for b in _chunks(zf, info, path):
                n += len(b)
                if n > MAX_MEMBER_BYTES or n > left:
                    raise _fail(path, f"member {info.filename!r} decompresses beyond the size limits "
                                f"({MAX_MEMBER_BYTES} per member, {limit} total)", "do not use this FMU")
                out.write(b)
        return n
    except FmuError:
        target.unlink(missing_ok=True)
        raise


def read_model_description(path: Path | str) -> ModelDescription:
    """Check the archive at ``path`` and parse its ``modelDescription.xml``.

    Does not extract anything to disk. Raises :class:`FmuError`.
    """
    path = Path(path)
    infos = check_archive(path)
    info = next(i for i in infos if i.filename == "modelDescription.xml")
    with _open_zip(path) as zf:
        xml = _read_member(zf, path, info, MAX_XML_BYTES)
    return parse_model_description(xml, path)


def platform_dir() -> str:
    """FMI 2.0 binaries folder name of this platform (e.g. ``linux64``)."""
    from fmpy import platform
    return platform


def binary_path(extracted: Path, md: ModelDescription) -> Path:
    """Path of the shared library of ``md`` in an extracted FMU; FmuError if missing."""
    from fmpy import sharedLibraryExtension
    lib = Path(extracted) / "binaries" / platform_dir() / (md.model_identifier + sharedLibraryExtension)
    if not lib.is_file():
        have = sorted(p.name for p in (Path(extracted) / "binaries").glob("*")) if (Path(extracted) / "binaries").is_dir() else []
        raise _fail(md.path, f"has no binary for this platform (expected binaries/{platform_dir()}/"
                    f"{lib.name}; platforms in the FMU: {have or 'none'})",
                    f"export the FMU with a {platform_dir()} binary ({sys.platform})")
    return lib


def cached_model_description(path: Path | str) -> ModelDescription:
    """:func:`read_model_description`, cached per file path, size and modification time
    (the scenario checks and the master read the same FMUs)."""
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return read_model_description(path)          # raises FmuError naming the missing file
    md = _read_cached(str(path), st.st_mtime_ns, st.st_size)
    read_log.note(path)              # read now or before: a recording scenario load depends on it
    return md


@functools.lru_cache(maxsize=64)
def _read_cached(path: str, mtime_ns: int, size: int) -> ModelDescription:
    return read_model_description(path)
