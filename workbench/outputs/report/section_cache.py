"""A problem's part of the report kept from one report to the next, and drawn again only
when what it is drawn from changed: a report rebuilt problem by problem (issue 35).

Drawing is most of a report's time (matplotlib, about 4 s of CPU a problem of the quick
suite). A sweep resumed, extended by a problem or with some runs redone changes the rows
of some problems, not of all. Each problem's section
(:class:`~workbench.outputs.report.page.ProblemSection`: its figures and drift table) is
described in ``figures/<anchor>.section.json`` with the key of everything it was drawn
from (:func:`section_key`) and the names, sizes and times of the files it wrote; the next
report into the same folder takes the section as it is when both still match.

The file is JSON read back field by field, never unpickled: a report folder may come
from someone else (docs/architecture.md, "Trust model"), and anything unexpected in it
only means the section is drawn again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.files import LinkRefusedError, open_no_follow, write_json_atomic
from workbench.outputs.report.figures import Axis, FigureFiles, slug
from workbench.outputs.report.page import PageTable, ProblemSection
from workbench.outputs.report.traits import Traits
from workbench.runs import output_keys

SUFFIX = ".section.json"
TABLE_SUFFIXES = ("csv", "md", "tex")  # what write_table writes of a table


def drawing_code_key() -> str:
    """The report's code and matplotlib's version: what draws every section (read once a
    report, not once a problem: it hashes the report package's files)."""
    import matplotlib

    return output_keys.key_of(
        output_keys.source_key("workbench.outputs.report"), matplotlib.__version__
    )


def section_key(
    runs: pd.DataFrame,
    series: Mapping[str, pd.DataFrame | None] | None,
    cost: str,
    traits: Traits,
    sketch: Any,
    formats: tuple[str, ...],
    code: str,
) -> str:
    """The key of a section drawn from these arguments of ``problem_section``, their
    content to the bit, by the code of ``code`` (:func:`drawing_code_key`)."""
    digest = hashlib.sha256()
    digest.update(_frame_digest(runs).encode())
    for run_id in sorted(series or {}):
        frame = (series or {})[run_id]
        digest.update(f"{run_id}\0{'-' if frame is None else _frame_digest(frame)}\0".encode())
    digest.update(_value_digest([
        series is None, cost, list(formats), traits.family, list(traits.traits),
        traits.stiffness, sorted(traits.drift_units),
        None if sketch is None else [getattr(sketch, f.name) for f in dataclasses.fields(sketch)],
    ]).encode())  # fmt: skip
    return output_keys.key_of(digest.hexdigest(), code)


def kept_section(out: Path, problem: str, key: str) -> ProblemSection | None:
    """The section of ``problem`` described in ``out``/figures for ``key``, if its files
    are still the ones it wrote; else None (none kept, another key, a file changed or
    gone, or a description this code does not read)."""
    path = out / "figures" / f"{slug(problem)}{SUFFIX}"
    try:
        with os.fdopen(open_no_follow(path, os.O_RDONLY, out), encoding="utf-8") as file:
            kept = json.load(file)
        if kept["key"] != key:
            return None
        section = _section(kept["section"])
        if (section.problem, section.anchor) != (problem, slug(problem)):
            return None
        files = section_files(out, section)
        if not all(f.is_file() for f in files) or output_keys.files_key(files) != kept["files"]:
            return None
    except (OSError, LinkRefusedError, ValueError, KeyError, TypeError):
        return None
    return section


def keep_section(out: Path, section: ProblemSection, key: str) -> None:
    """Describe ``section``, just drawn into ``out`` from the inputs of ``key``."""
    files = section_files(out, section)
    data = {"key": key, "files": output_keys.files_key(files), "section": _plain(section)}
    write_json_atomic(data, out / "figures" / f"{section.anchor}{SUFFIX}", durable=False, root=out)


def section_files(out: Path, section: ProblemSection) -> list[Path]:
    """The files a section's page shows or links: its figures in every format, its drift
    table's CSV, Markdown and LaTeX."""
    figures = [section.work_precision, section.picture, section.drift, section.error]
    files = [
        out / "figures" / f"{figure.stem}.{fmt}"
        for figure in figures
        if figure is not None
        for fmt in figure.formats
    ]
    if section.drift_table is not None:
        files += [out / "tables" / f"{section.drift_table.name}.{s}" for s in TABLE_SUFFIXES]
    return files


def _frame_digest(frame: pd.DataFrame) -> str:
    """A frame's columns, types, index and values, to the bit."""
    digest = hashlib.sha256(repr([(str(c), str(t)) for c, t in frame.dtypes.items()]).encode())
    digest.update(pd.util.hash_pandas_object(frame.index).to_numpy().tobytes())
    for column in frame.columns:
        values = frame[column]
        try:
            hashed = pd.util.hash_pandas_object(values, index=False)
        except TypeError:  # cells pandas does not hash (lists, dicts): by their text
            hashed = pd.util.hash_pandas_object(values.map(repr), index=False)
        digest.update(hashed.to_numpy().tobytes())
    return digest.hexdigest()


def _value_digest(value: Any) -> str:
    """Nested lists, tuples, arrays, numbers and texts, to the bit."""
    digest = hashlib.sha256()

    def add(item: Any) -> None:
        if isinstance(item, np.ndarray):
            digest.update(f"array {item.dtype} {item.shape}\0".encode())
            digest.update(np.ascontiguousarray(item).tobytes())
        elif isinstance(item, list | tuple):
            digest.update(f"seq {len(item)}\0".encode())
            for part in item:
                add(part)
        else:
            digest.update(f"{type(item).__name__} {item!r}\0".encode())

    add(value)
    return digest.hexdigest()


def _plain(section: ProblemSection) -> dict[str, Any]:
    data = dataclasses.asdict(dataclasses.replace(section, traits=None))
    traits = section.traits
    data["traits"] = None if traits is None else {
        "family": traits.family, "traits": list(traits.traits),
        "stiffness": traits.stiffness, "drift_units": sorted(traits.drift_units),
    }  # fmt: skip
    return data


def _section(data: dict[str, Any]) -> ProblemSection:
    """The section of :func:`_plain`'s data; TypeError or KeyError on anything else."""
    traits, rtol = data["traits"], data["rtol"]
    return ProblemSection(
        problem=_text(data["problem"]),
        anchor=_text(data["anchor"]),
        runs=_integer(data["runs"]),
        status_counts=_text(data["status_counts"]),
        work_precision=_figure(data["work_precision"]),
        rtol=None if rtol is None else _number(rtol),
        drift=_figure(data["drift"]),
        drift_table=_table(data["drift_table"]),
        error=_figure(data["error"]),
        picture=_figure(data["picture"]),
        traits=None if traits is None else _traits(traits),
        reference=_text(data["reference"]),
    )


def _traits(data: Any) -> Traits:
    return Traits(
        family=_text(data["family"]),
        traits=_texts(data["traits"]),
        stiffness=_text(data["stiffness"]),
        drift_units=set(_texts(data["drift_units"])),
    )


def _figure(data: Any) -> FigureFiles | None:
    if data is None:
        return None
    axes = [Axis(_text(a["label"]), _flag(a["numeric"])) for a in _list(data["axes"])]
    formats = tuple(_texts(data["formats"]))
    if not all(fmt.isalnum() for fmt in formats) or "/" in _text(data["stem"]):
        raise TypeError("not a figure of this folder")
    return FigureFiles(_text(data["stem"]), _text(data["caption"]), axes, formats)


def _table(data: Any) -> PageTable | None:
    if data is None:
        return None
    if "/" in _text(data["name"]):
        raise TypeError("not a table of this folder")
    rows = [_texts(row) for row in _list(data["rows"])]
    return PageTable(_text(data["name"]), _texts(data["header"]), rows)


def _text(value: Any) -> str:
    if not isinstance(value, str):
        raise TypeError(f"not a text: {value!r}")
    return value


def _texts(value: Any) -> list[str]:
    return [_text(item) for item in _list(value)]


def _list(value: Any) -> list[Any]:
    if not isinstance(value, list):
        raise TypeError(f"not a list: {value!r}")
    return value


def _integer(value: Any) -> int:
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"not an integer: {value!r}")
    return value


def _number(value: Any) -> float:
    if not isinstance(value, int | float) or isinstance(value, bool):
        raise TypeError(f"not a number: {value!r}")
    return float(value)


def _flag(value: Any) -> bool:
    if not isinstance(value, bool):
        raise TypeError(f"not true or false: {value!r}")
    return value
