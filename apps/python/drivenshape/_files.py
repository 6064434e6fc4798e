# SPDX-License-Identifier: Apache-2.0
"""Files as the package's tools (drivenshape.qc, drivenshape.usd) read and write them: inputs
told apart from outputs by file identity (device and inode after links) as well as by name,
inputs that must be regular files (a FIFO or a device is refused, never waited on), and the
mode a new file gets from the user's umask. Private to the package."""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterable
from typing import IO, Optional, Union

_Path = Union[str, "os.PathLike[str]"]
#: (option, path): a file a tool was given, named by the option that gave it (for messages).
NamedPath = tuple[str, _Path]


def identity(path: _Path) -> Optional[tuple[int, int]]:
    """(st_dev, st_ino) of the file `path` names after its links; None when there is none."""
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return None
    return info.st_dev, info.st_ino


def resolved(path: _Path) -> str:
    """The absolute name of `path` with every link followed (the parts that exist)."""
    return os.path.realpath(os.fspath(path))


def same_file(a: _Path, b: _Path) -> bool:
    """Whether `a` and `b` name one file: the same name after links, or the same device and
    inode (a hard link, a bind mount)."""
    if resolved(a) == resolved(b):
        return True
    first = identity(a)
    return first is not None and first == identity(b)


def check_distinct(outputs: Iterable[NamedPath], inputs: Iterable[NamedPath],
                   refuse: Callable[[str], Exception]) -> None:
    """Raises refuse(message) when an output names the file of an input (same_file), or two
    outputs name one file: an output never overwrites what a tool reads."""
    written: list[NamedPath] = []
    for option, path in outputs:
        for other_option, other in written:
            if same_file(path, other):
                raise refuse(f"{other_option} '{os.fspath(other)}' and {option} "
                             f"'{os.fspath(path)}' name the same file; give each output its "
                             "own name")
        written.append((option, path))
    for in_option, source in inputs:
        for option, path in written:
            if same_file(path, source):
                raise refuse(f"{option} '{os.fspath(path)}' would overwrite the input "
                             f"{in_option} '{os.fspath(source)}'; write the output elsewhere")


def kind_of(mode: int) -> str:
    """What a non-regular file is, in words."""
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return name
    return "not a regular file"


def regular_problem(path: _Path) -> Optional[str]:
    """Why `path` cannot be read as a regular file ("does not exist", "is a FIFO ..."), or
    None when it is one. Never opens the file."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return "does not exist"
    except OSError as error:
        return f"cannot be read: {error.strerror}"
    if not stat.S_ISREG(info.st_mode):
        return f"is {kind_of(info.st_mode)}, not a regular file"
    return None


def open_regular(path: _Path, limit: int, refuse: Callable[[str], Exception]) -> IO[bytes]:
    """`path` opened for reading, refused with refuse(message) unless it is a regular file of
    at most `limit` bytes. The open does not block (O_NONBLOCK: a FIFO without a writer is
    refused, not waited on); the checks are made on the opened file, so a name swapped between
    a check and the open cannot slip through."""
    name = os.fspath(path)
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise refuse(f"'{name}' does not exist")
    except IsADirectoryError:
        raise refuse(f"'{name}' is a folder, not a regular file")
    except OSError as error:
        raise refuse(f"cannot read '{name}': {error.strerror}")
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise refuse(f"'{name}' is {kind_of(info.st_mode)}, not a regular file")
        if info.st_size > limit:
            raise refuse(f"'{name}' holds {info.st_size} bytes, more than the {limit} this "
                         "reader takes")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def umask() -> int:
    """The process's umask, read without changing it where Linux says it (/proc)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # set and restored at once: the only portable way to read it
    os.umask(mask)
    return mask


def new_file_mode() -> int:
    """The mode open(..., "w") gives a new file: 0666 less the umask (0644 under 022)."""
    return 0o666 & ~umask()


def write_text_atomically(path: _Path, text: str) -> None:
    """Writes `text` (UTF-8) into a new file beside `path` and renames it into place: readers
    never see half a file; the file gets new_file_mode(). OSError on failure (the temporary
    file removed)."""
    import tempfile

    name = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(name))
    handle, temp = tempfile.mkstemp(prefix="." + os.path.basename(name) + ".tmp-", dir=folder)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.chmod(temp, new_file_mode())
        os.replace(temp, name)
    except BaseException:
        if os.path.lexists(temp):
            os.remove(temp)
        raise
