"""The exceptions selfcal raises: the standard library's kinds, with :class:`Error` their common base.

A missing file raises a :class:`FileNotFoundError` (here :class:`MissingFileError`), a file the
system refuses a :class:`PermissionError`, a folder named as a file an :class:`IsADirectoryError`,
bad content or a bad argument value a :class:`ValueError` (:class:`InputError`), an argument of
the wrong type a :class:`TypeError` (:class:`ArgumentTypeError`); every one is also a
:class:`selfcal.Error`, so ``except selfcal.Error`` catches them all.

Only the standard base classes that share a memory layout are combined: OSError and ValueError are
never bases of one class.
"""


class Error(Exception):
    """The common base of every exception selfcal raises.

    The message is the library's one line, ``FILE:LINE: reason`` when the problem is in a file,
    as the command line prints it after ``selfcal:``.
    """


class InputError(Error, ValueError):
    """Bad content: a malformed file, an inconsistent plan, a value out of range, an unknown key."""


class UnsolvableError(InputError):
    """The data or the plan do not determine the unknowns (e.g. a plan that does not identify G)."""


class ArgumentTypeError(Error, TypeError):
    """An argument of the wrong type (text where a number is needed, an unknown keyword)."""


class FileError(Error, OSError):
    """The system refused a file. ``errno``, ``strerror`` and ``filename`` are those of the call
    that failed; ``str()`` is the library's one-line message."""

    #: the library's one-line message (``str(e)``); None: the standard OSError text
    message: "str | None" = None

    def __str__(self) -> str:
        return self.message if self.message is not None else OSError.__str__(self)


class MissingFileError(FileError, FileNotFoundError):
    """The path names no file (ENOENT, or a path component that is not a folder: ENOTDIR)."""


class FilePermissionError(FileError, PermissionError):
    """The system does not let this process read or write the file (EACCES, EPERM, EROFS)."""


class DirectoryError(FileError, IsADirectoryError):
    """A folder was named where a file is needed (EISDIR)."""


class OutOfMemoryError(Error, MemoryError):
    """An allocation failed, or a solve would need more memory than allowed (``max_memory``)."""


class InternalError(Error, RuntimeError):
    """A numerical or internal failure that should not happen (please report it)."""


for _cls in (Error, InputError, UnsolvableError, ArgumentTypeError, FileError, MissingFileError,
             FilePermissionError, DirectoryError, OutOfMemoryError, InternalError):
    _cls.__module__ = "selfcal"  # shown as selfcal.InputError, where users find them
del _cls

__all__ = ["Error", "InputError", "UnsolvableError", "ArgumentTypeError", "FileError",
           "MissingFileError", "FilePermissionError", "DirectoryError", "OutOfMemoryError",
           "InternalError"]
