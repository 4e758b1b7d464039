"""Where a robot file may make the workbench read: its own folder, the package roots the
user names, and folders the user allows (docs/architecture.md, "Trust model"; docs/robots.md).

A robot file is data from someone else. Each file it names (a URDF mesh, an MJCF
``<include>``, mesh, texture or height field) is resolved here, symbolic links included,
and read only if it lands inside

* the robot file's folder (``../`` and absolute paths that leave it are refused);
* for ``package://NAME/...``: the package NAME found in a package root: the
  ``package_path`` the user gives (``--package-path``, the sweep key ``package_path``),
  then ``ROS_PACKAGE_PATH``, then the robot's folder. A root holds packages as its
  sub-folders (ROOT/NAME), or is one itself (its folder name is NAME); the file must stay
  inside that package's folder;
* a folder in ``allow_roots`` (``--allow-root``): any reference may land there.

Anything else is a one-line :class:`~workbench.errors.ModelError` naming the element and the
reference, where it leads and how to allow it. Only regular files are read (not devices,
FIFOs, folders), of at most ``max_bytes`` (100 MB unless configured).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlsplit

from workbench.errors import ModelError

DEFAULT_MAX_MB = 100.0
"""The largest file (MB, 10^6 bytes) a robot file may make the workbench read."""

ROS_PACKAGE_PATH = "ROS_PACKAGE_PATH"


def _real(path: str | os.PathLike[str]) -> Path:
    """``path`` absolute, with every symbolic link and ``..`` resolved."""
    return Path(os.path.realpath(os.path.abspath(os.path.expanduser(str(path)))))


def _inside(path: Path, root: Path) -> bool:
    return path == root or path.is_relative_to(root)


@dataclass(frozen=True)
class FileRoots:
    """The folders a robot file at ``folder`` may read from (see the module docstring).

    folder: the robot file's folder; package_path: package roots the user names, searched
    before ``ROS_PACKAGE_PATH``; allow_roots: folders any reference may reach;
    max_bytes: the size limit of every file read.
    """

    folder: Path
    package_path: tuple[Path, ...] = ()
    allow_roots: tuple[Path, ...] = ()
    max_bytes: int = int(DEFAULT_MAX_MB * 1e6)

    @classmethod
    def of(
        cls,
        robot_file: str | os.PathLike[str],
        package_path: Iterable[str | os.PathLike[str]] = (),
        allow_roots: Iterable[str | os.PathLike[str]] = (),
        max_mb: float = DEFAULT_MAX_MB,
    ) -> FileRoots:
        """The roots of ``robot_file``: its folder, ``package_path`` then the folders of
        ``ROS_PACKAGE_PATH``, and ``allow_roots`` (all made absolute and real)."""
        ros = [part for part in os.environ.get(ROS_PACKAGE_PATH, "").split(os.pathsep) if part]
        return cls(
            folder=_real(Path(robot_file).parent if str(robot_file) else "."),
            package_path=tuple(_real(p) for p in [*package_path, *ros]),
            allow_roots=tuple(_real(p) for p in allow_roots),
            max_bytes=int(float(max_mb) * 1e6),
        )

    # -- resolving a reference --------------------------------------------------------
    def resolve(
        self, reference: str, where: str, what: str = "mesh", bases: Iterable[Path] = ()
    ) -> Path | None:
        """The real path of the file ``reference`` names, checked; None if it is missing.

        reference: as written in the file (a relative path, an absolute one, ``file://``
        or ``package://``); where: the element, for messages ("FILE: link 'arm' (line
        4)"); what: what the reference is ("mesh", "include"); bases: the folders a
        relative path is taken from (default: the robot's folder; several when the file
        format leaves it open: every one must stay inside). Refused (ModelError): any
        candidate outside the roots, not a regular file, or larger than the limit.
        """
        text = reference.strip()
        scheme = urlsplit(text).scheme.lower() if "://" in text else ""
        if scheme == "package":
            return self._package(text, where, what)
        if scheme == "file":
            text = unquote(text[len("file://") :])
        elif scheme:
            raise ModelError(
                f"{where}: {what} {reference!r}: a {scheme}:// address is not read (only "
                "files: a path, file:// or package://); put the file beside the robot file"
            )
        if os.path.isabs(os.path.expanduser(text)):
            candidates = [Path(os.path.expanduser(text))]
        else:
            candidates = [base / text for base in (list(bases) or [self.folder])]
        found = None
        for candidate in candidates:
            real = self._checked(candidate, self.folder, reference, where, what)
            found = found or real
        return found

    def _package(self, reference: str, where: str, what: str) -> Path | None:
        rest = reference[len("package://") :].lstrip("/")
        name, _, inner = rest.partition("/")
        if not name or name in (".", "..") or not inner:
            raise ModelError(
                f"{where}: {what} {reference!r}: not a package file (write "
                "package://PACKAGE/path/in/package)"
            )
        found = None
        for package in self.packages(name):
            real = self._checked(package / inner, package, reference, where, what)
            found = found or real
        return found

    def packages(self, name: str) -> list[Path]:
        """The folders of package ``name`` in the package roots, then the robot's folder."""
        found = []
        for root in (*self.package_path, self.folder):
            for candidate in (root / name, root):
                if candidate.name == name and candidate.is_dir():
                    real = _real(candidate)
                    if real not in found:
                        found.append(real)
        return found

    def _checked(
        self, candidate: Path, root: Path, reference: str, where: str, what: str
    ) -> Path | None:
        real = _real(candidate)
        if not (_inside(real, root) or any(_inside(real, a) for a in self.allow_roots)):
            lexical = Path(os.path.normpath(os.path.abspath(candidate)))
            link = " through a symbolic link" if lexical != real else ""
            raise ModelError(
                f"{where}: {what} {reference!r} leads{link} to {real}, outside {root}; a "
                "robot file reads only files in its own folder and in the package roots you "
                "name (--package-path); if you trust the file, allow its folder with "
                f"--allow-root {real.parent}"
            )
        return self.regular_file(real, reference, where, what)

    def check_folder(self, reference: str, where: str, what: str, bases: Iterable[Path]) -> None:
        """Refuse (ModelError) a folder ``reference`` (e.g. MJCF ``meshdir``) that leads
        outside the robot's folder and ``allow_roots`` from any of ``bases``."""
        text = os.path.expanduser(reference.strip())
        for candidate in [Path(text)] if os.path.isabs(text) else [b / text for b in bases]:
            real = _real(candidate)
            if not (_inside(real, self.folder) or any(_inside(real, a) for a in self.allow_roots)):
                raise ModelError(
                    f"{where}: {what} {reference!r} leads to {real}, outside {self.folder}; a "
                    "robot file reads only files in its own folder; if you trust the file, "
                    f"allow that folder with --allow-root {real}"
                )

    def where_looked(self, reference: str) -> str:
        """Where :meth:`resolve` looked for ``reference``, for a "not found" message."""
        if reference.strip().lower().startswith("package://"):
            name = reference.strip()[len("package://") :].lstrip("/").partition("/")[0]
            roots = [str(root) for root in (*self.package_path, self.folder)]
            return (
                f"package {name!r} looked for in {', '.join(roots)} (name the folder holding "
                f"it with --package-path, or set {ROS_PACKAGE_PATH})"
            )
        return f"looked in {self.folder}"

    def regular_file(self, real: Path, reference: str, where: str, what: str) -> Path | None:
        """``real`` if it is a regular file within the size limit; None if it is missing."""
        try:
            status = os.stat(real)
        except FileNotFoundError:
            return None
        except OSError as error:
            raise ModelError(f"{where}: {what} {reference!r} ({real}) cannot be read: "
                             f"{error.strerror}") from None  # fmt: skip
        if not stat.S_ISREG(status.st_mode):
            raise ModelError(
                f"{where}: {what} {reference!r} is {real}, not a regular file (a device, "
                "pipe or folder is never read); name a file"
            )
        if status.st_size > self.max_bytes:
            raise ModelError(
                f"{where}: {what} {reference!r} ({real}) has {status.st_size / 1e6:.1f} MB, "
                f"more than the limit of {self.max_bytes / 1e6:g} MB; raise it with the "
                "option max_file_mb if you trust the file"
            )
        return real


def read_regular_file(path: str | os.PathLike[str]) -> bytes:
    """The bytes of ``path``, a regular file reached without a symbolic link in its last
    part (the importers keep real paths): what a recording reads of a checked mesh."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    descriptor = os.open(path, flags)
    with os.fdopen(descriptor, "rb") as file:
        if not stat.S_ISREG(os.fstat(file.fileno()).st_mode):
            raise OSError(f"{path} is not a regular file")
        return file.read()


__all__ = ["DEFAULT_MAX_MB", "FileRoots", "read_regular_file"]
