"""An MJCF file's XML read before MuJoCo compiles it, so that the compiler opens no file
outside the robot's roots and takes no non-finite number.

MuJoCo reads files the XML names (``<include file>``, ``<mesh file>``, textures'
``file``/``fileleft``/..., height fields, skins, ``<model file>``) relative to the main
file's folder or the including file's folder, and for assets below ``meshdir`` /
``texturedir`` / ``assetdir`` (MuJoCo 4.0 tries several of these). Every such reading
must stay inside the roots (:class:`~workbench.model.importers.file_roots.FileRoots`), so
an attribute whose name starts with ``file`` is checked from each of those folders, the
``*dir`` attributes themselves too, and included files are read (checked the same way)
and searched in turn.

MuJoCo takes ``mass="nan"`` and replaces it silently (a density-derived mass), so any
attribute holding a number that is not finite (``nan``, ``inf``, ``1e999``) is refused,
as the URDF reader does; names and references to other elements are not numbers and are
left alone.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from workbench.errors import ModelError
from workbench.model.importers.file_roots import FileRoots

DIRECTORY_ATTRIBUTES = ("meshdir", "texturedir", "assetdir")
TEXT_ATTRIBUTES = {
    "name", "class", "childclass", "prefix", "suffix", "model", "content_type", "plugin",
    "instance", "key", "value", "data", "target", "objname", "refname", "material", "mesh",
    "texture", "hfield", "skin", "flex", "body", "body1", "body2", "joint", "joint1",
    "joint2", "geom", "geom1", "geom2", "site", "site1", "site2", "tendon", "tendon1",
    "tendon2", "actuator", "camera", "light", "cranksite", "slidersite", "jointinparent",
    "childsite", "parent", "frame",
}  # fmt: skip
"""Attributes that hold names or text, never numbers."""

NON_FINITE = re.compile(r"[+-]?(nan|inf|infinity)(\(.*\))?", re.IGNORECASE)
MAX_INCLUDE_DEPTH = 20


def check_mjcf_source(path: Path, roots: FileRoots) -> None:
    """Refuse (one-line ModelError) an MJCF file at ``path`` that names a file outside
    ``roots`` or holds a non-finite number, in it or in a file it includes."""
    documents = _documents(path, roots)
    directories = [""]
    for _file, root in documents:
        for element in root.iter("compiler"):
            for attribute in DIRECTORY_ATTRIBUTES:
                if element.get(attribute):
                    directories.append(element.get(attribute))
    for file, root in documents:
        for element in root.iter():
            if not isinstance(element.tag, str):
                continue  # comments, processing instructions
            _check_numbers(file, element)
            _check_files(file, element, path.parent, roots, directories)


def _where(file: Path, element: Any) -> str:
    name = element.get("name")
    named = f" name={name!r}" if name else ""
    return f"{file}: <{element.tag}{named}> (line {element.sourceline})"


def _parse(file: Path) -> Any:
    from lxml import etree

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
    try:
        return etree.parse(str(file), parser).getroot()
    except etree.XMLSyntaxError as error:
        raise ModelError(
            f"{file}: broken XML at line {error.lineno}: {error.msg}; fix the file so it is "
            "well-formed XML"
        ) from None
    except OSError as error:
        raise ModelError(f"{file}: cannot read the file: {error}") from None


def _documents(path: Path, roots: FileRoots) -> list[tuple[Path, Any]]:
    """(file, root element) of the MJCF file and every file it includes, recursively."""
    documents: list[tuple[Path, Any]] = []
    pending: list[tuple[Path, int]] = [(path, 0)]
    seen: set[Path] = set()
    while pending:
        file, depth = pending.pop()
        root = _parse(file)
        documents.append((file, root))
        for element in root.iter("include"):
            reference = element.get("file")
            if not reference:
                continue
            where = _where(file, element)
            found = roots.resolve(reference, where, "include", [path.parent, file.parent])
            if found is None:
                continue  # MuJoCo names the missing file
            if depth + 1 > MAX_INCLUDE_DEPTH:
                raise ModelError(f"{where}: includes nested deeper than {MAX_INCLUDE_DEPTH}")
            if found not in seen:
                seen.add(found)
                pending.append((found, depth + 1))
    return documents


def _check_numbers(file: Path, element: Any) -> None:
    if element.tag == "text":  # <custom><text data="..."> is free text
        return
    for attribute, text in element.attrib.items():
        if attribute in TEXT_ATTRIBUTES or attribute.startswith("file"):
            continue
        if attribute in DIRECTORY_ATTRIBUTES:
            continue
        for word in text.split():
            if NON_FINITE.fullmatch(word) or _overflows(word):
                raise ModelError(
                    f"{_where(file, element)}: {attribute}={text!r} is not a finite number "
                    "(or list of numbers); write it as decimal numbers"
                )


def _overflows(word: str) -> bool:
    try:
        return not math.isfinite(float(word))
    except ValueError:
        return False


def _check_files(
    file: Path, element: Any, model_folder: Path, roots: FileRoots, directories: list[str]
) -> None:
    bases = list(dict.fromkeys([model_folder, file.parent]))
    for attribute, text in element.attrib.items():
        if element.tag == "compiler" and attribute in DIRECTORY_ATTRIBUTES:
            roots.check_folder(text, _where(file, element), attribute, bases)
        elif attribute.startswith("file") and text.strip() and element.tag != "include":
            folders = [base / directory for base in bases for directory in directories]
            roots.resolve(text, _where(file, element), attribute, list(dict.fromkeys(folders)))


__all__ = ["check_mjcf_source"]
