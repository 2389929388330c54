"""The Python binding against the command line: the shipped campaign identified from numpy
arrays gives the parameters `robopost identify` gives from the file; a fixture program
compensated in memory is byte for byte what `robopost IN.src -c CAL.json -o OUT.src` writes,
with its `.dat`, the cell's `$config.dat` and frames given by number."""

import csv
import json
import math

import numpy as np
import pytest

import robopost

CAMPAIGN = "fixtures/measurements/campaign-hidden.csv"
CALIBRATION = "calibrations/kr30ha-example.json"


def read_columns(path):
    """The measurement CSV read with Python's csv module into numpy arrays (not robopost's
    reader): test labels, axes (n × 6), positions (n × 3, NaN where not measured), times."""
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f)]
    test = [r["test"] for r in rows]
    axes = np.array([[float(r[f"a{k}"]) for k in range(1, 7)] for r in rows])
    positions = np.array(
        [[float(r[c]) if r[c] != "" else math.nan for c in "xyz"] for r in rows]
    )
    times = np.array([float(r["t"]) for r in rows])
    return test, axes, positions, times


def numbers(value, path=""):
    """Every number of a JSON value with its path (for comparing two calibrations)."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from numbers(v, f"{path}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from numbers(v, f"{path}[{i}]")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        yield path, float(value)


@pytest.fixture(scope="module")
def campaign(root):
    test, axes, positions, times = read_columns(root / CAMPAIGN)
    return robopost.Measurements(test, axes, positions, times, source="campaign-hidden")


@pytest.fixture(scope="module")
def identified(campaign):
    return robopost.identify(campaign)


def test_identify_from_arrays_equals_the_command_line(root, cli, identified, tmp_path):
    cli("identify", root / CAMPAIGN, "-o", tmp_path / "cli.json")
    mine = identified["calibration"].to_dict()
    theirs = json.loads((tmp_path / "cli.json").read_text())
    # The model: robot, target, frame and every effect's parameters and table values.
    keys = ("robot", "target_mm", "frame", "effects")
    got = dict(n for k in keys for n in numbers(mine[k], k))
    want = dict(n for k in keys for n in numbers(theirs[k], k))
    assert got.keys() == want.keys()
    assert len(want) > 1000  # the paper's model: geometry, 12 tables, crosstalk
    for path, w in want.items():
        assert got[path] == pytest.approx(w, rel=1e-9, abs=1e-12), path
    assert [e["name"] for e in mine["effects"]] == [e["name"] for e in theirs["effects"]]
    # The fit reaches the campaign's noise: its residual is tens of µm where the nominal
    # robot's is tenths of a millimetre.
    assert identified["failure"] is None
    assert identified["stats"]["rms_um"] < 40 < identified["initial_stats"]["rms_um"]


def test_identify_takes_a_pandas_frame(root, identified):
    pandas = pytest.importorskip("pandas")
    frame = pandas.read_csv(root / CAMPAIGN)
    result = robopost.identify(frame)
    assert result["calibration"].to_dict()["effects"] == identified["calibration"].to_dict()["effects"]


def test_compare_and_diagnose_return_plain_data(identified, campaign):
    stats = robopost.compare(identified["calibration"], campaign)
    assert stats["points"] == sum(1 for p in campaign.positions if not math.isnan(p[0]))
    # compare's residual over every point; identify's over the points not left out as gross.
    assert stats["rms_um"] >= identified["stats"]["rms_um"] - 1e-9
    diagnosis = robopost.diagnose(identified["calibration"], campaign, learn=False)
    assert isinstance(diagnosis, dict) and diagnosis
    json.dumps(diagnosis)  # plain data


def test_bad_measurements_are_located(root, campaign):
    axes = campaign.axes.copy()
    axes[4, 2] = math.inf
    bad = robopost.Measurements(campaign.test, axes, campaign.positions, campaign.times, "mine")
    with pytest.raises(ValueError, match=r"^mine:5:4: command angle A3"):
        robopost.compare(robopost.Calibration.from_file(root / CALIBRATION), bad)


@pytest.mark.parametrize(
    "program, cell, cli_args",
    [
        ("fixtures/programs/paper_path1", {}, []),
        (
            "fixtures/programs/teach/pick_place",
            {"config": "fixtures/config/$config.dat", "points": "offline"},
            ["--config", "fixtures/config/$config.dat", "--points", "offline"],
        ),
        (
            "fixtures/programs/cam_frame_array/contour_cnc",
            {
                "bases": {4: (1200, -250, 400, 15, 0, 0)},
                "tools": {5: (0, 0, 180, 0, 0, 0)},
            },
            ["--base", "4=1200,-250,400,15,0,0", "--tool", "5=0,0,180,0,0,0"],
        ),
    ],
)
def test_compensate_equals_the_command_line(root, cli, tmp_path, program, cell, cli_args):
    src = (root / f"{program}.src").read_bytes()
    dat_path = root / f"{program}.dat"
    dat = dat_path.read_bytes() if dat_path.exists() else None
    kwargs = dict(cell)
    if "config" in kwargs:
        kwargs["config"] = (root / kwargs["config"]).read_bytes()
    cal = robopost.Calibration.from_file(root / CALIBRATION)
    done = robopost.compensate(src, cal, name=f"{program}.src", dat=dat, **kwargs)
    cli(f"{program}.src", "-c", CALIBRATION, "-o", tmp_path / "out.src", *cli_args)
    assert done["source"] == (tmp_path / "out.src").read_bytes()
    assert done["source"] != src
    assert done["report"]["compensated"] > 0
    if dat is not None:
        assert done["dat"] == (tmp_path / "out.dat").read_bytes()


def test_compensate_text_in_text_out(root):
    src = (root / "fixtures/programs/paper_path1.src").read_bytes()
    cal = robopost.Calibration.from_file(root / CALIBRATION)
    as_bytes = robopost.compensate(src, cal, name="p.src")
    as_text = robopost.compensate(src.decode("utf-8"), cal, name="p.src")
    assert as_text["source"].encode("utf-8") == as_bytes["source"]


def test_a_broken_program_is_a_value_error(root):
    cal = robopost.Calibration.from_file(root / CALIBRATION)
    with pytest.raises(ValueError, match=r"bad\.src:2:"):
        robopost.compensate("DEF bad( )\nLIN\nEND\n", cal, name="bad.src")
