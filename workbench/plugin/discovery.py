"""Entry-point plugins that crash or hang on import are found in a child process first.

An exception in a plugin's import is caught by the registry, but a segfault or an import
that never returns took ``workbench list`` and every other command down with it (issue
18.13). So before the registry imports the entry points of other packages, each is
imported once in a child process (``python -m workbench.plugin.discovery``), one after
the other: one that kills the child is reported as "import crashed (signal 11)", one that
has not finished after :func:`import_timeout` seconds as "import did not finish in N s",
and the registry lists it as broken without importing it. The rest (including a plugin
whose import raises, which the registry reports with its own traceback) are imported
in-process as before.

The verdicts are kept in ``<user cache>/plugin-probes.json`` under a key made of every
entry point with its distribution's name and version, the Python executable and the
workbench version: the probe runs again only when that changes (a plugin installed,
upgraded or removed). An installed plugin whose behaviour changes without a new version
(an editable install) is caught by a marker: while the registry imports entry points it
keeps ``import-<pid>.pending`` in the cache; a marker left by a process that no longer
runs means that import crashed or was killed, and the next discovery probes again.
Without entry points in the workbench groups nothing of this happens.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from importlib import metadata
from pathlib import Path

from workbench import __version__
from workbench.errors import one_line
from workbench.files import atomic_write, user_cache_dir

VERDICTS_FILE = "plugin-probes.json"
TIMEOUT_VARIABLE = "WORKBENCH_PLUGIN_IMPORT_TIMEOUT"
DEFAULT_TIMEOUT = 60.0  # s: only an import that hangs takes that long
OK = ""  # the verdict of an entry point that is safe to import in-process


def import_timeout() -> float:
    """Seconds one entry point's import may take in the probe (``$WORKBENCH_PLUGIN_IMPORT_TIMEOUT``,
    default 60)."""
    try:
        value = float(os.environ.get(TIMEOUT_VARIABLE, ""))
    except ValueError:
        return DEFAULT_TIMEOUT
    return value if value > 0 else DEFAULT_TIMEOUT


def entry_point_key(entry_point: metadata.EntryPoint) -> str:
    return f"{entry_point.group}:{entry_point.name}={entry_point.value}"


def environment_key(entry_points: list[metadata.EntryPoint]) -> str:
    """A hash of the entry points, their distributions' versions and the interpreter."""
    parts = [sys.executable, sys.version, __version__]
    for entry_point in entry_points:
        dist = getattr(entry_point, "dist", None)
        name = dist.metadata["Name"] if dist is not None else ""
        version = dist.version if dist is not None else ""
        parts.append(f"{entry_point_key(entry_point)} {name} {version}")
    return hashlib.sha256("\n".join(sorted(parts)).encode()).hexdigest()[:24]


def verdicts(entry_points: list[metadata.EntryPoint]) -> dict[str, str]:
    """entry point key -> OK or the reason it must not be imported in this process."""
    if not entry_points:
        return {}
    cache = user_cache_dir()
    key = environment_key(entry_points)
    stored = _read_verdicts(cache / VERDICTS_FILE)
    if stored.get("key") == key and not _crashed_imports(cache):
        return dict(stored.get("verdicts", {}))
    found = probe(entry_points)
    with contextlib.suppress(OSError):
        cache.mkdir(parents=True, exist_ok=True)
        text = json.dumps({"key": key, "verdicts": found}, indent=1)
        atomic_write(cache / VERDICTS_FILE, lambda name: Path(name).write_text(text), False)
        for marker in cache.glob("import-*.pending"):
            _remove_if_dead(marker)
    return found


@contextlib.contextmanager
def importing() -> Iterator[None]:
    """Mark this process as importing entry points (see the module docstring)."""
    marker = user_cache_dir() / f"import-{os.getpid()}.pending"
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text(str(os.getpid()))
    except OSError:
        marker = None
    try:
        yield
    finally:
        if marker is not None:
            with contextlib.suppress(OSError):
                marker.unlink()


def probe(entry_points: list[metadata.EntryPoint]) -> dict[str, str]:
    """Import each entry point in a child process; key -> OK or why it is broken."""
    requests = [(e.name, e.value, e.group) for e in entry_points]
    found: dict[str, str] = {}
    start = 0
    while start < len(requests):
        start = _probe_from(requests, start, found)
    return found


def _probe_from(requests: list[tuple[str, str, str]], start: int, found: dict[str, str]) -> int:
    """Probe ``requests[start:]`` in one child; returns where the next child starts."""
    limit = import_timeout()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p or os.getcwd() for p in sys.path)
    child = subprocess.Popen(
        [sys.executable, "-m", "workbench.plugin.discovery"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
        env=env, start_new_session=True,
    )  # fmt: skip
    assert child.stdin is not None and child.stdout is not None
    child.stdin.write(json.dumps(requests[start:]).encode())
    child.stdin.close()
    current, began, buffer = None, time.monotonic(), b""
    try:
        while True:
            waited = limit - (time.monotonic() - began) if current is not None else limit * 4
            ready, _, _ = select.select([child.stdout], [], [], max(waited, 0.0))
            if not ready:  # the current import hangs (or the child never started)
                index = start if current is None else current
                found[_key(requests[index])] = f"import did not finish in {limit:g} s"
                return index + 1
            chunk = os.read(child.stdout.fileno(), 4096)
            if not chunk:  # the child is gone
                code = child.wait()
                if current is None:
                    return len(requests)  # finished every request
                found[_key(requests[current])] = _death(code)
                return current + 1
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                verb, _, index_text = line.decode().partition(" ")
                index = start + int(index_text)
                if verb == "start":
                    current, began = index, time.monotonic()
                elif verb == "done":
                    found[_key(requests[index])] = OK
                    current = None
    finally:
        if child.poll() is None:
            with contextlib.suppress(OSError):
                os.killpg(child.pid, signal.SIGKILL)
            child.wait()
        child.stdout.close()


def _key(request: tuple[str, str, str]) -> str:
    name, value, group = request
    return f"{group}:{name}={value}"


def _death(code: int) -> str:
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = "signal"
        return f"import crashed ({name}, signal {-code})"
    return f"import ended the process (exit code {code})"


def _read_verdicts(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _crashed_imports(cache: Path) -> bool:
    """A marker of a process that no longer runs: its import crashed or hung."""
    for marker in cache.glob("import-*.pending"):
        if not _alive(marker):
            return True
    return False


def _alive(marker: Path) -> bool:
    try:
        pid = int(marker.stem.split("-", 1)[1].split(".")[0])
        os.kill(pid, 0)
    except (ValueError, IndexError, ProcessLookupError):
        return False
    except PermissionError:
        return True
    return True


def _remove_if_dead(marker: Path) -> None:
    if not _alive(marker):
        with contextlib.suppress(OSError):
            marker.unlink()


def _probe_main() -> None:
    """The child: import each (name, value, group) from stdin, saying so on its stdout.

    Plugins' own output goes to stderr, so stdout carries only "start i" and "done i"."""
    protocol = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    requests = json.loads(sys.stdin.read())
    for index, (name, value, group) in enumerate(requests):
        protocol.write(f"start {index}\n")
        try:
            metadata.EntryPoint(name=name, value=value, group=group).load()
        except BaseException as error:  # noqa: BLE001 - a Python error is the registry's to report
            print(one_line(error), file=sys.stderr)
        protocol.write(f"done {index}\n")


if __name__ == "__main__":
    _probe_main()
