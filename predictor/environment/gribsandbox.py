"""GRIB files this process did not write are decoded in a child process with memory, CPU and time limits.

Why: eccodes is C. Whatever the byte-level checks (``gribframe``) do not foresee can still make it read
past a buffer, corrupt its heap or loop, and in the process that serves others (`drs serve predictor`,
the console) that is one request from the end of the service. In a child, whatever eccodes does, the
caller gets one ``WeatherFileError`` naming the file and the fault: a refusal, a crash (the signal), an
allocation over ``MEMORY_LIMIT_BYTES``, or more than the time limit.

The child is this module run as ``python -m``: it sets its own limits before eccodes loads, reads the
files with ``gribread.read_grib_planes`` and hands back the cropped planes as ``.npz`` arrays (no pickle)
in a private folder, with the grid's header values; the parent rebuilds the grid from those values and
checks every array's shape against it. Files written by this process (``gribwrite.written_here``: the demo
weather, test fixtures) are read in-process: a writer is not an attacker. Overhead: see ``drs weather bench``
and the report of issue #31 (one child per load, not per file).
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from predictor.environment.gribframe import check_grib_framing
from predictor.environment.gribwrite import written_here
from predictor.errors import WeatherError, WeatherFileError

MEMORY_LIMIT_BYTES = 3 * 2**30
"""The child's address space: eccodes, numpy and one global 0.25° field decoded (8 MB) fit in a tenth of
it; a header that asks for more is damaged. A lower limit inherited from the caller is kept."""
TIME_LIMIT_S = 30.0
TIME_PER_BYTE_S = 1.0 / 10e6
"""Wall and CPU time the child may take: 30 s plus 1 s per 10 MB of GRIB (a whole 0.25° GFS file of
500 MB, every message walked: 80 s; it decodes in about a tenth of that on this 2-core machine)."""


def read_planes(files: Sequence[Path], box: Any) -> list[Any]:
    """Every file's u, v, t and gh planes cropped to ``box`` (``gribread.GribPlanes``), in order.

    Every file's framing is checked here first (pure Python); files written by this process are then
    decoded here, all others in one child process. Raises WeatherFileError naming the first bad file.
    """
    from predictor.environment.gribread import read_grib_planes

    for file in files:
        check_grib_framing(file)
    foreign = [file for file in files if not written_here(file)]
    decoded = dict(zip(foreign, _in_child(foreign, box), strict=True)) if foreign else {}
    return [decoded[file] if file in decoded else read_grib_planes(file, box) for file in files]


def _limits(files: Sequence[Path]) -> tuple[int, float]:
    size = sum(file.stat().st_size for file in files)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    memory = MEMORY_LIMIT_BYTES
    for inherited in (soft, hard):
        if inherited != resource.RLIM_INFINITY:
            memory = min(memory, inherited)
    return memory, TIME_LIMIT_S + size * TIME_PER_BYTE_S


def _in_child(files: Sequence[Path], box: Any) -> list[Any]:
    memory, seconds = _limits(files)
    with tempfile.TemporaryDirectory(prefix="drs-grib-") as spool:
        request = json.dumps({"files": [str(f) for f in files], "box": box})
        package_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [package_root, env.get("PYTHONPATH")]))
        with open(Path(spool) / "stderr", "wb") as errors:
            child = subprocess.Popen(
                [sys.executable, "-m", __name__, str(memory), str(int(seconds) + 1), spool],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=errors, env=env,
            )  # fmt: skip
            started = time.monotonic()
            try:
                out, _ = child.communicate(request.encode(), timeout=seconds)
                overtime = False
            except subprocess.TimeoutExpired:
                child.kill()
                out, _ = child.communicate()
                overtime = True
        said = _answers(out)
        reading = files[said["reading"]] if "reading" in said else files[0]
        if "refused" in said:
            raise _refusal(files[said["refused"]], said.get("message", ""))
        if overtime:
            raise WeatherFileError(
                reading, f"took over {seconds:.0f} s to decode (stopped); the file is damaged or hostile"
            )
        if child.returncode != 0:
            raise WeatherFileError(reading, _death(child.returncode, memory, time.monotonic() - started))
        if said.get("done") != len(files):
            raise WeatherFileError(reading, "the GRIB decoder process ended without an answer")
        return [_load(file, Path(spool) / f"{index}.npz", box) for index, file in enumerate(files)]


def _answers(out: bytes) -> dict[str, Any]:
    """The child's last word on each key (``reading``, ``refused``, ``message``, ``done``); lines that
    are not its JSON (a crash mid-line) are ignored."""
    said: dict[str, Any] = {}
    for line in out.splitlines()[-10_000:]:
        try:
            item = json.loads(line)
        except ValueError:
            continue
        if isinstance(item, dict):
            said.update(item)
    return said


def _refusal(file: Path, message: str) -> WeatherFileError:
    text, name = str(message), str(file)
    if text.startswith(name):
        return WeatherFileError(file, text[len(name) :].lstrip(": "), said=text)
    return WeatherFileError(file, text)


def _death(returncode: int, memory: int, seconds: float) -> str:
    if returncode < 0:
        name = signal.Signals(-returncode).name if -returncode in signal.valid_signals() else str(-returncode)
        if -returncode == signal.SIGXCPU:
            return f"took over its CPU time to decode ({name}); the file is damaged or hostile"
        return f"made the GRIB decoder crash ({name}, after {seconds:.1f} s); the file is damaged or hostile"
    return (
        f"made the GRIB decoder process fail (exit status {returncode}; memory limit "
        f"{memory / 2**30:.1f} GiB); the file is damaged or hostile"
    )


def _load(file: Path, stored: Path, box: Any) -> Any:
    """The child's planes for one file, re-checked: the grid is rebuilt here from its header values and
    every array must have its shape."""
    from predictor.environment.gribread import GribPlanes, grid_of

    malformed = WeatherFileError(file, "the GRIB decoder's answer is malformed")
    try:
        with np.load(stored, allow_pickle=False) as arrays:
            meta = json.loads(str(arrays["meta"]))
            signature = tuple(meta["signature"])
            if len(signature) != 7 or not all(isinstance(v, int | float) for v in signature):
                raise malformed
            grid = grid_of(file, signature, box)
            shape = (grid.lat_index.size, grid.lon_index.size)
            planes: dict[Any, Any] = {}
            for cycle, valid, name, level, key in meta["planes"]:
                plane = arrays[str(key)]
                if plane.shape != shape or plane.dtype != np.float64:
                    raise malformed
                when = (np.datetime64(str(cycle), "s"), np.datetime64(str(valid), "s"))
                planes.setdefault(when, {}).setdefault(str(name), {})[float(level)] = plane
            processes = {int(p) for p in meta["processes"]}
    except (OSError, KeyError, TypeError, ValueError) as exc:
        raise malformed from exc
    return GribPlanes((file,), grid, planes, processes)


def _store(target: Path, planes: Any) -> None:
    arrays: dict[str, Any] = {}
    entries = []
    for (cycle, valid), by_name in planes.planes.items():
        for name, by_level in by_name.items():
            for level, plane in by_level.items():
                key = f"p{len(arrays)}"
                arrays[key] = np.ascontiguousarray(plane, dtype=np.float64)
                entries.append([str(cycle), str(valid), name, float(level), key])
    meta = {
        "signature": list(planes.grid.signature),
        "planes": entries,
        "processes": sorted(planes.processes),
    }
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(target, **arrays)


def _say(item: dict[str, Any]) -> None:
    sys.stdout.write(json.dumps(item) + "\n")
    sys.stdout.flush()


def _child(argv: Sequence[str]) -> int:
    """The child: limits first, then each file in turn, saying which one it is on before touching it."""
    memory, seconds, spool = int(argv[0]), int(argv[1]), Path(argv[2])
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    resource.setrlimit(resource.RLIMIT_CPU, (seconds, seconds + 5))
    from predictor.environment.gribread import read_grib_planes

    request = json.loads(sys.stdin.read())
    box = tuple(request["box"]) if request["box"] is not None else None
    for index, name in enumerate(request["files"]):
        _say({"reading": index})
        try:
            _store(spool / f"{index}.npz", read_grib_planes(Path(name), box))
        except WeatherError as exc:
            _say({"refused": index, "message": str(exc)})
            return 0
        except MemoryError:
            _say({"refused": index, "message": f"needs over {memory / 2**30:.1f} GiB to decode; damaged?"})
            return 0
        except Exception as exc:  # eccodes or numpy on a header nothing foresaw: still this file's fault
            _say({"refused": index, "message": f"does not decode ({type(exc).__name__}: {exc})"})
            return 0
    _say({"done": len(request["files"])})
    return 0


if __name__ == "__main__":
    sys.exit(_child(sys.argv[1:]))
