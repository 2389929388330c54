"""robopost for Python: compensate KUKA KRL programs with a calibrated error model, identify a
calibration from laser-tracker measurements, compare and diagnose it.

Plain data in and out: programs are ``str`` or ``bytes``, measurements are numpy arrays or a
pandas data frame, results are dicts, lists and floats (the same numbers and names as the
command line's ``--json`` and ``--report`` outputs, docs/python.md). Every error robopost
reports is a ``ValueError`` whose message is the command line's (``file:line:col`` and the
offending line for a program).

>>> import robopost
>>> cal = robopost.Calibration.from_file("calibrations/kr30ha-example.json")
>>> done = robopost.compensate(open("prog.src").read(), cal, name="prog.src")
>>> done["report"]["compensated"]
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

__all__ = [
    "Calibration",
    "Measurements",
    "compensate",
    "identify",
    "compare",
    "diagnose",
    "PAPER_EFFECTS",
]

#: The paper's full model: the axis lines' geometry, each axis's angle map and gear play, and
#: the crosstalk of A3 onto A2 (the default effects of :func:`identify`).
PAPER_EFFECTS: str = _native.PAPER_EFFECTS


@dataclass(frozen=True)
class Calibration:
    """A calibration file (``robopost-calibration/2`` JSON, docs/calibration.md).

    ``text`` is the file's JSON text; ``name`` is the file's name, which a compensated
    program's header names together with the SHA-256 of the text (as the command line writes
    it). The text is checked when the calibration is made: a value out of its physical range
    or a malformed file is a ``ValueError``.
    """

    text: str
    name: str = "calibration.json"

    def __post_init__(self) -> None:
        object.__setattr__(self, "robot_name", _native.check_calibration(self.text, self.name))

    @classmethod
    def from_file(cls, path: Union[str, os.PathLike]) -> "Calibration":
        """Reads a calibration file; its name (without directory) is what headers name."""
        with open(path, "rb") as f:
            text = f.read().decode("utf-8")
        return cls(text, os.path.basename(os.fspath(path)))

    @classmethod
    def from_json(cls, text: str, name: str = "calibration.json") -> "Calibration":
        """A calibration from its JSON text; ``name`` names it in messages and headers."""
        return cls(text, name)

    def to_dict(self) -> Dict[str, Any]:
        """The calibration file as a dict (``json.loads`` of its text)."""
        return json.loads(self.text)


def _floats(values: Any, columns: int, what: str) -> np.ndarray:
    array = np.ascontiguousarray(np.asarray(values, dtype="<f8"))
    if columns == 1:
        array = array.reshape(-1)
    elif array.ndim != 2 or array.shape[1] != columns:
        raise ValueError(f"{what}: expected an array of shape (n, {columns}), got {array.shape}")
    return array


class Measurements:
    """Laser-tracker measurements of one set (a file, one tracker station), built in memory:
    one entry per robot stop, in the order the robot visited them (the rows of the
    measurement CSV, docs/measurements.md).

    * ``test``: the label of each stop's test or path (n strings);
    * ``axes``: the command angles A1..A6, degrees (n × 6);
    * ``positions``: the measured target position x, y, z, mm (n × 3); all three NaN on a
      stop that was visited but not measured (an approach row);
    * ``times``: seconds since the start of the campaign (n), or ``None``;
    * ``source``: the set's name in messages and reports (like a file name).

    Each axis's rotation direction and gear-play history are inferred from the order of the
    stops, as for a file. The values are checked when robopost uses them: a bad one is a
    ``ValueError`` located as ``source:ROW:COLUMN`` (rows from 1, columns counted as
    ``test, a1..a6, x, y, z, t``).
    """

    def __init__(
        self,
        test: Sequence[str],
        axes: Any,
        positions: Any,
        times: Any = None,
        source: str = "measurements",
    ) -> None:
        self.test: List[str] = [str(t) for t in test]
        self.axes = _floats(axes, 6, "axes")
        self.positions = _floats(positions, 3, "positions")
        self.times = None if times is None else _floats(times, 1, "times")
        self.source = source

    @classmethod
    def from_frame(cls, frame: Any, source: str = "measurements") -> "Measurements":
        """From a pandas data frame with the measurement CSV's columns: ``test``,
        ``a1``..``a6``, ``x``, ``y``, ``z`` (NaN where not measured) and optionally ``t``
        (column names in any case)."""
        columns = {str(c).strip().lower(): c for c in frame.columns}

        def column(name: str) -> Any:
            if name not in columns:
                raise ValueError(f"{source}: required column `{name}` is missing")
            return frame[columns[name]].to_numpy(dtype="float64", na_value=np.nan)

        test = [str(t) for t in frame[columns["test"]]] if "test" in columns else column("test")
        axes = np.column_stack([column(f"a{k}") for k in range(1, 7)])
        positions = np.column_stack([column(c) for c in ("x", "y", "z")])
        times = column("t") if "t" in columns else None
        return cls(test, axes, positions, times, source)

    def __len__(self) -> int:
        return len(self.test)

    def _native(self) -> Tuple[str, List[str], bytes, bytes, Optional[bytes]]:
        times = None if self.times is None else self.times.tobytes()
        return (self.source, self.test, self.axes.tobytes(), self.positions.tobytes(), times)


MeasurementsLike = Union[Measurements, Any, Iterable[Union[Measurements, Any]]]


def _sets(data: MeasurementsLike) -> List[Tuple[str, List[str], bytes, bytes, Optional[bytes]]]:
    """One set or several: a :class:`Measurements`, a pandas frame, or a list of them."""
    if isinstance(data, Measurements) or hasattr(data, "columns"):
        data = [data]
    out = []
    for k, d in enumerate(data):
        if not isinstance(d, Measurements):
            d = Measurements.from_frame(d, source=f"set{k + 1}")
        out.append(d._native())
    return out


def _calibration(calibration: Union[Calibration, str, os.PathLike]) -> Calibration:
    if isinstance(calibration, Calibration):
        return calibration
    return Calibration.from_file(calibration)


def compensate(
    program: Union[str, bytes],
    calibration: Union[Calibration, str, os.PathLike],
    *,
    name: str = "program.src",
    dat: Union[str, bytes, None] = None,
    config: Union[str, bytes, None] = None,
    bases: Optional[Dict[int, Sequence[float]]] = None,
    tools: Optional[Dict[int, Sequence[float]]] = None,
    points: str = "auto",
) -> Dict[str, Any]:
    """Compensates a KRL program (the text of its ``.src``) with ``calibration``, as
    ``robopost IN.src -c CAL.json -o OUT.src`` does: only the numbers that must change are
    rewritten, with a header naming the calibration.

    The cell: ``dat`` is the program's own data list (its ``.dat``), ``config`` the robot's
    ``$config.dat`` (``--config``), ``bases`` and ``tools`` frames by number as
    ``{n: (X, Y, Z, A, B, C)}`` (``--base``/``--tool``), ``points`` which points are
    compensated: ``"auto"`` (as the program's files say), ``"offline"`` (all) or ``"taught"``
    (none). ``name`` names the program in messages and the report.

    ``program``, ``dat`` and ``config`` are ``bytes`` (byte for byte as the files are, the
    controller's Windows-1252 included) or ``str`` (taken as UTF-8).

    Returns a dict: ``source`` and ``dat`` (the new texts, ``str`` when the program was given
    as ``str``, else ``bytes``; ``dat`` is ``None`` without one), ``report`` (the ``--report`` JSON as a dict:
    counts, corrections, predicted errors) and ``messages`` (warnings and per-target errors as
    the command line prints them). A program that cannot be walked at all is a
    ``ValueError``.
    """
    cal = _calibration(calibration)
    as_text = isinstance(program, str)

    def raw(x: Union[str, bytes, None]) -> Optional[bytes]:
        # robopost keeps every byte it does not rewrite: text given as str goes in as UTF-8
        # and comes back decoded the same way (bytes in, bytes out for a Windows-1252 file).
        return x.encode("utf-8", "surrogateescape") if isinstance(x, str) else x

    frames = [(True, int(n), [float(v) for v in p]) for n, p in (bases or {}).items()]
    frames += [(False, int(n), [float(v) for v in p]) for n, p in (tools or {}).items()]
    source, new_dat, report, messages = _native.compensate(
        name, raw(program), cal.text, cal.name, raw(dat), raw(config), frames, points
    )
    text = (lambda b: b.decode("utf-8", "surrogateescape")) if as_text else (lambda b: b)
    return {
        "source": text(source),
        "dat": None if new_dat is None else text(new_dat),
        "report": json.loads(report),
        "messages": list(messages),
    }


def identify(
    data: MeasurementsLike,
    *,
    effects: Optional[str] = None,
    frame: str = "base",
    map_pitch: float = 1.0,
    calibration: Union[Calibration, str, os.PathLike, None] = None,
    target: Optional[Sequence[float]] = None,
    robot_name: Optional[str] = None,
    max_points: Optional[int] = None,
    tracker: Optional[str] = None,
    tracker_at: Optional[Sequence[float]] = None,
) -> Dict[str, Any]:
    """Identifies a calibration from measurements, as ``robopost identify`` does with the same
    options (docs/cli.md): the same parameters for the same data.

    ``data`` is one :class:`Measurements` or pandas frame, or a list of them (one per file or
    tracker station). ``effects``: contract names (``"geometric,map:A1..A6"``; default
    :data:`PAPER_EFFECTS`; ``"+NAME"`` adds to ``calibration``). ``frame``: ``"base"`` or
    ``"tracker"`` (a tracker frame identified per set). ``map_pitch``: the grid of the map and
    backlash tables, degrees. ``target``: a hint for the reflector in the flange frame, mm.
    ``tracker``/``tracker_at``: the tracker's preset or MPE and its station, mm.

    Returns a dict: ``calibration`` (a :class:`Calibration`, as ``identify -o`` writes it),
    ``effects``, ``parameters`` (a list of dicts: ``name``, ``value``, ``unit``,
    ``standard_error``, ``status``), ``stats``/``initial_stats``/``per_test`` (residual
    statistics, µm, the keys of the paper's Table 1), ``sigma_um``, ``iterations``,
    ``converged``, ``rounds``, ``gross_errors`` (left out of the fit), ``tracker_frames``,
    ``noise_floor_rms_um``, ``failure`` (why the fit is not good enough to use, or ``None``:
    the command line refuses to write such a calibration), ``note`` and ``warnings``.
    """
    if frame not in ("base", "tracker"):
        raise ValueError(f"frame: expected `base` or `tracker`, found `{frame}`")
    triple = lambda v: None if v is None else [float(x) for x in v]  # noqa: E731
    out = json.loads(
        _native.identify(
            _sets(data),
            effects,
            frame == "tracker",
            float(map_pitch),
            None if calibration is None else _calibration(calibration).text,
            triple(target),
            robot_name,
            max_points,
            tracker,
            triple(tracker_at),
        )
    )
    out["calibration"] = Calibration(out["calibration"], "identified.json")
    return out


def compare(
    calibration: Union[Calibration, str, os.PathLike], data: MeasurementsLike
) -> Dict[str, float]:
    """The residual (measured − predicted) of ``calibration`` at every measured point of
    ``data``, as the statistics of the paper's Table 1 in µm: ``points``, ``xy_mean_um``,
    ``xy_2sigma_um``, ``z_mean_um``, ``z_2sigma_um``, ``d3_mean_um``, ``d3_max_um``,
    ``rms_um``."""
    cal = _calibration(calibration)
    return json.loads(_native.compare(cal.text, cal.name, _sets(data)))


def diagnose(
    calibration: Union[Calibration, str, os.PathLike],
    data: MeasurementsLike,
    *,
    learn: bool = True,
    folds: int = 4,
) -> Dict[str, Any]:
    """Where ``calibration`` fails on ``data`` and which physical effect it most likely
    misses: ``robopost diagnose --json``'s result as a dict (findings with the share of the
    residual each explains, the evidence, and the effect to add). ``learn``: also learn the
    residual's drivers; ``folds``: folds of the cross-validation."""
    cal = _calibration(calibration)
    return json.loads(_native.diagnose(cal.text, cal.name, _sets(data), learn, folds))
