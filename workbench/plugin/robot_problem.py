"""The problem of a robot read from a file: ``workbench run robot.urdf``, a sweep entry
``{ urdf = "robot.urdf" }`` or ``{ mjcf = "scene.xml" }`` (docs/robots.md).

The problem "robot" takes the file as its option ``file`` (an absolute path, so a run's id
names the file wherever the run executes); the command line and the sweep specification
turn a path into it (:func:`robot_problem_options`). A run of it is named after its file
and the options that differ from the defaults (``solo12.urdf[floating_base=true]``,
:func:`robot_problem_name`), so that several robots of one sweep stay distinct problems in
rows, report and recording; the registry resolves such a name to this problem.

The robot moves unforced under gravity from ``q0`` / ``v0`` ({joint: value}, or one list
of every tree joint's coordinates in the file's order), else the file's keyframe (MJCF),
else the neutral configuration at rest. Its energy is conserved unless the file has joint dampers.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from workbench.errors import ConfigError, ModelError
from workbench.model import JointSpringDamper, Model
from workbench.model.importers import ImportedRobot, load_robot, robot_format
from workbench.model.importers.file_roots import DEFAULT_MAX_MB
from workbench.plugin.options import with_unit
from workbench.plugin.problem import Problem
from workbench.plugin.registry import problem

ROBOT_PROBLEM = "robot"
ENTRY_KEYS = ("urdf", "mjcf")


FILE_OPTIONS = ("file", "package_path", "allow_roots")
"""The options of :class:`RobotOptions` that name files or folders a run reads."""


@dataclass(frozen=True)
class RobotOptions:
    file: str = ""
    t_end: float = with_unit(1.0, "s")
    n_samples: int = 101
    q0: Any = None
    v0: Any = None
    floating_base: bool = False  # URDF: a free joint under the root link
    mimic: Literal["error", "independent"] = "error"  # URDF mimic joints
    keyframe: int = 0  # MJCF: the keyframe of the initial state, if the file has one
    package_path: tuple[str, ...] = ()  # folders holding the packages package:// names
    allow_roots: tuple[str, ...] = ()  # folders outside the file's own it may read
    max_file_mb: float = with_unit(DEFAULT_MAX_MB, "MB")  # the largest file it may read
    meshes: bool = True  # URDF: False imports without checking the visual mesh files
    drop: tuple[str, ...] = ()  # MJCF: terms the model cannot hold, left out (DROPPABLE)

    def __post_init__(self) -> None:
        for name in ("package_path", "allow_roots"):
            value = getattr(self, name)
            if isinstance(value, str) or not all(isinstance(p, str) and p for p in value):
                raise ConfigError(f"option {name} must be a list of folders, not {value!r}")
            object.__setattr__(self, name, tuple(value))
        if not self.max_file_mb > 0:
            raise ConfigError(f"max_file_mb must be > 0 MB, not {self.max_file_mb}")
        if not self.file:
            raise ConfigError("option 'file' is required: the path of a .urdf or MJCF .xml file")
        if robot_format(self.file) is None:
            raise ConfigError(f"file {self.file!r}: give a .urdf or an MJCF .xml file")
        if not self.t_end > 0:
            raise ConfigError(f"t_end must be > 0 s, not {self.t_end}")
        if self.n_samples < 2:
            raise ConfigError(f"n_samples must be >= 2, not {self.n_samples}")


@functools.cache
def _imported(
    file: str,
    floating_base: bool,
    mimic: str,
    keyframe: int,
    roots: tuple[Any, ...],
    meshes: bool,
    drop: tuple[str, ...],
) -> ImportedRobot:
    package_path, allow_roots, max_file_mb = roots
    where = {"package_path": package_path, "allow_roots": allow_roots, "max_file_mb": max_file_mb}
    if robot_format(file) == "urdf":
        return load_robot(file, floating_base=floating_base, mimic=mimic, meshes=meshes, **where)
    return load_robot(file, keyframe=keyframe, drop=drop, **where)


@problem
class RobotProblem(Problem):
    name = ROBOT_PROBLEM
    summary = "A robot read from a URDF or MJCF file (option file), moving unforced under gravity"
    source = "the file named by the option file (URDF: ROS URDF spec; MJCF: MuJoCo XML reference)"
    Options = RobotOptions
    listed = False  # needs its file: named, never part of "all" or the catalog's listings

    def __init__(self, options: Any = None) -> None:
        super().__init__(options)
        self.name = robot_problem_name(dataclasses.asdict(self.options))
        self.t_end = float(self.options.t_end)
        self.n_samples = int(self.options.n_samples)

    def imported(self) -> ImportedRobot:
        o = self.options
        roots = (o.package_path, o.allow_roots, o.max_file_mb)
        return _imported(
            o.file, o.floating_base, o.mimic, o.keyframe, roots, o.meshes, tuple(o.drop or ())
        )

    def model(self) -> Model:
        model = copy.deepcopy(self.imported().model)
        model.initial_configuration = self.initial_joint_coordinates()
        return model

    @property
    def conservative(self) -> bool:  # type: ignore[override]
        return not any(
            isinstance(force, JointSpringDamper) and force.damping
            for force in self.imported().model.forces
        )

    def initial_joint_coordinates(self) -> dict[str, Any]:
        given = self._values(self.options.q0, "q0", coordinates=True)
        return given if given is not None else dict(self.imported().initial_coordinates)

    def initial_joint_velocities(self) -> dict[str, Any]:
        given = self._values(self.options.v0, "v0", coordinates=False)
        return given if given is not None else dict(self.imported().initial_velocities)

    def describe_rows(self) -> list[tuple[str, str]]:
        imported = self.imported()
        limits = ", ".join(
            f"{joint} {low:g} .. {high:g}" for joint, (low, high) in imported.limits.items()
        )
        welded = [link for link, (body, _) in imported.links.items() if link != body]
        return [
            ("file", str(imported.source)),
            ("links welded", ", ".join(welded) or "none"),
            ("joint limits (not enforced)", limits or "none"),
            ("meshes", str(len(imported.meshes))),
            *(("not modelled", note) for note in imported.notes),
        ]

    def _values(self, value: Any, option: str, coordinates: bool) -> dict[str, Any] | None:
        """{joint: value} from a table by joint name or a list in tree-joint order."""
        from workbench.mechanics.joints import DIMENSIONS

        if value is None:
            return None
        joints = [j for j in self.imported().model.tree_joints if j.drive is None]
        if isinstance(value, dict):
            unknown = sorted(set(value) - {j.name for j in joints})
            if unknown:
                names = ", ".join(j.name for j in joints)
                raise ConfigError(
                    f"problem 'robot', option {option}: {unknown[0]!r} is not a joint of "
                    f"{Path(self.options.file).name} (its joints: {names})"
                )
            return dict(value)
        if isinstance(value, list | tuple):
            sizes = [DIMENSIONS[j.type][0 if coordinates else 1] for j in joints]
            if len(value) != sum(sizes):
                raise ConfigError(
                    f"problem 'robot', option {option}: {len(value)} values for {sum(sizes)} "
                    "joint coordinates; give one per coordinate in the file's joint order "
                    "(`workbench describe FILE`) or a table {joint = value}"
                )
            result, start = {}, 0
            for joint, size in zip(joints, sizes, strict=True):
                part = list(value[start : start + size])
                result[joint.name] = part[0] if size == 1 else part
                start += size
            return result
        raise ConfigError(
            f"problem 'robot', option {option}: give a table {{joint = value}} or a list of "
            f"numbers, not {value!r}"
        )


def check_robot_file(problem: Any) -> None:
    """A robot problem's file, model and ``q0`` / ``v0`` read now (other problems: nothing):
    ConfigError naming what is wrong before any run, not each run's failure."""
    if not isinstance(problem, RobotProblem):
        return
    try:
        problem.model()  # the file, its model and q0
        problem.initial_joint_velocities()
    except ModelError as error:
        raise ConfigError(str(error)) from None


def robot_problem_options(path: str | Path, base: Path | None = None) -> dict[str, Any]:
    """The "robot" problem's options for a robot file ``path`` (relative to ``base``,
    default the working directory); ConfigError if it is missing."""
    resolved = (Path(base or Path.cwd()) / Path(path).expanduser()).resolve()
    if not resolved.is_file():
        raise ConfigError(f"robot file {str(path)!r} not found (looked for {resolved})")
    return {"file": str(resolved)}


def robot_entries(problems: Any, base: Path, fail: Any) -> Any:
    """A sweep's ``problems`` with every ``{ urdf = PATH, ... }`` or ``{ mjcf = PATH, ... }``
    entry turned into ``{ name = "robot", options = { file = ABSOLUTE PATH, ... } }``; the
    other keys of the entry are the robot problem's options, PATH is relative to ``base``
    (the specification's folder). ``fail(key, message)`` makes the ConfigError."""
    if not isinstance(problems, list):
        return problems
    entries = []
    for index, item in enumerate(problems):
        keys = [key for key in ENTRY_KEYS if isinstance(item, dict) and key in item]
        if not keys:
            entries.append(item)
            continue
        key = f"problems[{index}].{keys[0]}"
        if len(keys) > 1 or "name" in item or "options" in item:
            raise fail(key, "a robot entry names one file (urdf or mjcf) and its options")
        path = item[keys[0]]
        if not isinstance(path, str) or not path:
            raise fail(key, f"must be the path of a robot file, not {path!r}")
        expected = "urdf" if keys[0] == "urdf" else "mjcf"
        if robot_format(path) != expected:
            raise fail(key, f"{path!r} is not a {expected.upper()} file (.urdf / .xml)")
        try:
            options = robot_problem_options(path, base)
        except ConfigError as error:
            raise fail(key, str(error)) from None
        options.update({k: v for k, v in item.items() if k != keys[0]})
        for name in FOLDER_OPTIONS:  # folders relative to the specification; one value
            if name in options:  # (a list here is not a grid of runs)
                folders = options[name]
                if not isinstance(folders, list) or not all(isinstance(f, str) for f in folders):
                    raise fail(f"problems[{index}].{name}", "must be a list of folders")
                options[name] = [[_folder(folder, base) for folder in folders]]
        entries.append({"name": ROBOT_PROBLEM, "options": options})
    return entries


FOLDER_OPTIONS = ("package_path", "allow_roots")
# where the files are read from and how large they may be: not part of a problem's name
NAMELESS_OPTIONS = ("file", *FOLDER_OPTIONS, "max_file_mb")


def _folder(path: str | Path, base: Path | None = None) -> str:
    """A folder named by the user, absolute (relative to ``base``, default the working
    directory), so a run's options name it wherever the run executes."""
    return str((Path(base or Path.cwd()) / Path(path).expanduser()).resolve())


def robot_problem_name(options: Mapping[str, Any], folders: int = 0) -> str:
    """The name of a run of the robot problem with ``options``: the file's name (with
    ``folders`` parent folders), then the options that differ from the defaults,
    ``name[key=value,...]`` (keys sorted, values as compact JSON without quotes)."""
    path = Path(str(options.get("file", "")))
    name = "/".join([*path.parent.parts[len(path.parent.parts) - folders :], path.name])

    def plain(value: Any) -> str:  # () and [] alike: options come back from JSON as lists
        return json.dumps(value, sort_keys=True, default=str)

    defaults = {f.name: plain(f.default) for f in dataclasses.fields(RobotOptions)}
    changed = {
        key: value
        for key, value in options.items()
        if key not in NAMELESS_OPTIONS and defaults.get(key) != plain(value)
    }
    if not changed:
        return name
    text = ",".join(
        f"{key}={json.dumps(changed[key], separators=(',', ':'), default=str)}"
        for key in sorted(changed)
    )
    return f"{name}[{text.replace(chr(34), '')}]"


def is_robot_problem_name(name: str) -> bool:
    """``name`` is a robot problem's run name (a robot file's name, options in brackets)."""
    return robot_format(name.split("[", 1)[0]) is not None


def run_problem_names(problems: Sequence[tuple[str, Mapping[str, Any]]]) -> list[str]:
    """The problem name of each (registered name, options) in runs: a robot problem's is
    :func:`robot_problem_name`, with as many parent folders as tell its file apart from
    other files of the same name; the others keep theirs."""

    def robot(name: str) -> bool:
        return name == ROBOT_PROBLEM or is_robot_problem_name(name)

    files = {str(options.get("file", "")) for name, options in problems if robot(name)}
    folders = {}
    for file in files:
        depth = 0
        while depth < 32 and any(
            robot_problem_name({"file": other}, depth) == robot_problem_name({"file": file}, depth)
            for other in files - {file}
        ):
            depth += 1
        folders[file] = depth
    return [
        robot_problem_name(options, folders[str(options.get("file", ""))]) if robot(name) else name
        for name, options in problems
    ]


def robot_file_problem(
    problem: str,
    option: list[str],
    package_path: list[str] | None = None,
    allow_roots: list[str] | None = None,
) -> tuple[str, list[str]]:
    """A robot file named where a problem is (``workbench run/describe robot.urdf``) -> the
    "robot" problem and its ``-o problem.file=...`` first among the ``-o`` options, with
    ``--package-path`` and ``--allow-root`` folders (absolute) as its options."""
    import json

    if robot_format(problem) is None:
        if package_path or allow_roots:
            raise ConfigError(
                f"--package-path and --allow-root are for robot files; {problem!r} is not one"
            )
        return problem, option
    path = robot_problem_options(problem)["file"]
    given = [f"problem.file={json.dumps(path)}"]
    for name, folders in (("package_path", package_path), ("allow_roots", allow_roots)):
        if folders:
            given.append(f"problem.{name}={json.dumps([_folder(f) for f in folders])}")
    return ROBOT_PROBLEM, [*given, *option]


__all__ = [
    "ENTRY_KEYS",
    "ROBOT_PROBLEM",
    "RobotProblem",
    "is_robot_problem_name",
    "robot_entries",
    "robot_file_problem",
    "robot_problem_name",
    "robot_problem_options",
    "run_problem_names",
]
