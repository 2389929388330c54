//! `robopost._native`: the extension module under the `robopost` Python package. Thin over
//! robopost's library API: arguments come as plain Python values (numbers in little-endian
//! `float64` bytes, as numpy's `tobytes` gives them), results go back as plain values or
//! JSON text, which the package's Python side (`robopost/__init__.py`) turns into dicts and
//! documents. Every robopost error is a `ValueError` with the command line's message.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use serde_json::{json, Value};

use robopost::{
    CalibrationSource, CellContext, CellFrame, DiagnoseOptions, IdentifyOptions,
    MeasurementColumns, Measurements, Taken,
};

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// `bytes` of little-endian `float64`s, `width` per row.
fn floats<const N: usize>(bytes: &[u8], what: &str) -> PyResult<Vec<[f64; N]>> {
    if bytes.len() % (8 * N) != 0 {
        return Err(value_error(format!(
            "{what}: {} bytes are not rows of {N} float64 values",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(8 * N)
        .map(|row| {
            std::array::from_fn(|k| {
                let mut b = [0u8; 8];
                b.copy_from_slice(&row[8 * k..8 * k + 8]);
                f64::from_le_bytes(b)
            })
        })
        .collect())
}

/// One measurement set as the Python side passes it: its name, the test labels, the axes
/// (n × 6), the positions (n × 3, NaN where not measured) and the times (n, or none).
type Set = (String, Vec<String>, Vec<u8>, Vec<u8>, Option<Vec<u8>>);

fn measurements(sets: Vec<Set>) -> PyResult<Vec<Measurements>> {
    sets.into_iter()
        .map(|(source, test, axes, positions, times)| {
            let axes = floats::<6>(&axes, "axes")?;
            let position = floats::<3>(&positions, "positions")?;
            let time = times
                .map(|t| floats::<1>(&t, "times"))
                .transpose()?
                .map(|t| t.into_iter().map(|[v]| v).collect::<Vec<f64>>());
            let columns = MeasurementColumns {
                test: &test,
                axes_deg: &axes,
                position_mm: &position,
                time_s: time.as_deref(),
            };
            robopost::measurements_from_columns(&source, &columns).map_err(value_error)
        })
        .collect()
}

fn calibration(text: &str, name: &str) -> PyResult<robopost::Calibration> {
    robopost::parse_calibration(text, name).map_err(value_error)
}

fn to_text(value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(value_error)
}

/// Compensates a program: `(source, dat or None, report JSON, messages)`.
#[pyfunction]
#[pyo3(signature = (name, source, calibration_json, calibration_name, dat=None, config=None, frames=Vec::new(), points="auto"))]
#[allow(clippy::too_many_arguments)]
fn compensate<'py>(
    py: Python<'py>,
    name: &str,
    source: &[u8],
    calibration_json: &str,
    calibration_name: &str,
    dat: Option<Vec<u8>>,
    config: Option<Vec<u8>>,
    frames: Vec<(bool, i64, [f64; 6])>,
    points: &str,
) -> PyResult<(
    Bound<'py, PyBytes>,
    Option<Bound<'py, PyBytes>>,
    String,
    Vec<String>,
)> {
    let cal = calibration(calibration_json, calibration_name)?;
    let points = match points {
        "auto" => Taken::Auto,
        "offline" => Taken::Offline,
        "taught" => Taken::Taught,
        other => {
            return Err(value_error(format!(
                "points: expected `auto`, `offline` or `taught`, found `{other}`"
            )))
        }
    };
    let context = CellContext {
        dat,
        config,
        frames: frames
            .into_iter()
            .map(|(base, index, xyzabc)| CellFrame {
                base,
                index,
                xyzabc,
            })
            .collect(),
        points,
        calibration_file: Some(CalibrationSource {
            name: calibration_name.to_string(),
            bytes: calibration_json.as_bytes().to_vec(),
        }),
    };
    let done = py
        .detach(|| robopost::compensate_in_cell(name, source, &cal, &context))
        .map_err(value_error)?;
    Ok((
        PyBytes::new(py, &done.source),
        done.dat.map(|d| PyBytes::new(py, &d)),
        to_text(&done.report)?,
        done.messages,
    ))
}

/// Identifies a calibration: the result as JSON text (see `robopost.identify`).
#[pyfunction]
#[pyo3(signature = (sets, effects=None, tracker_frame=false, map_pitch_deg=1.0, calibration_json=None, target_mm=None, robot_name=None, max_points=None, tracker=None, tracker_at_mm=None))]
#[allow(clippy::too_many_arguments)]
fn identify(
    py: Python<'_>,
    sets: Vec<Set>,
    effects: Option<String>,
    tracker_frame: bool,
    map_pitch_deg: f64,
    calibration_json: Option<&str>,
    target_mm: Option<[f64; 3]>,
    robot_name: Option<String>,
    max_points: Option<usize>,
    tracker: Option<String>,
    tracker_at_mm: Option<[f64; 3]>,
) -> PyResult<String> {
    let files = measurements(sets)?;
    let options = IdentifyOptions {
        effects,
        tracker_frame,
        map_pitch_deg,
        calibration: calibration_json
            .map(|t| calibration(t, "calibration"))
            .transpose()?,
        target_mm,
        robot_name,
        max_points,
        tracker,
        tracker_at_mm,
    };
    let r = py
        .detach(|| robopost::identify_with(&files, &options))
        .map_err(value_error)?;
    let cal_json = r
        .calibration
        .to_json(std::path::Path::new("identified"))
        .map_err(value_error)?;
    let fit = &r.fit;
    let values = r.calibration.parameter_values();
    let parameters: Vec<Value> = fit
        .parameter_names
        .iter()
        .enumerate()
        .map(|(i, name)| {
            json!({
                "name": name,
                "value": values.get(i),
                "unit": fit.units[i],
                "standard_error": fit.standard_errors[i],
                "status": format!("{:?}", fit.status[i]).to_lowercase(),
            })
        })
        .collect();
    let frames: Vec<Value> = fit
        .tracker_frames
        .iter()
        .zip(&fit.tracker_frames_standard_errors)
        .map(|(f, se)| {
            let p = f.to_pose();
            json!({"xyzabc": [p.x, p.y, p.z, p.a, p.b, p.c], "standard_errors": se})
        })
        .collect();
    let gross: Vec<Value> = r
        .gross
        .iter()
        .map(|g| {
            json!({"row": g.row, "source": g.file, "line": g.line, "test": g.test,
                   "size_um": g.size_um, "why": g.why})
        })
        .collect();
    let out = json!({
        "calibration": cal_json,
        "effects": r.effects,
        "parameters": parameters,
        "stats": r.stats,
        "initial_stats": fit.initial_stats,
        "per_test": r.per_test,
        "sigma_um": fit.sigma_mm * 1000.0,
        "iterations": fit.iterations,
        "converged": fit.converged,
        "rounds": r.rounds,
        "gross_errors": gross,
        "tracker_frames": frames,
        "noise_floor_rms_um": r.verdict.noise.rms_um,
        "failure": r.verdict.failure,
        "note": r.verdict.note,
        "warnings": r.physical.iter().cloned()
            .chain(fit.warnings.iter().map(|w| w.to_string()))
            .collect::<Vec<String>>(),
    });
    Ok(out.to_string())
}

/// The residual statistics of a calibration on measurements, as JSON text.
#[pyfunction]
fn compare(
    py: Python<'_>,
    calibration_json: &str,
    calibration_name: &str,
    sets: Vec<Set>,
) -> PyResult<String> {
    let cal = calibration(calibration_json, calibration_name)?;
    let files = measurements(sets)?;
    let stats = py.detach(|| robopost::compare(&cal, &files));
    to_text(&stats)
}

/// A diagnosis of a calibration on measurements, as JSON text (`diagnose --json`'s).
#[pyfunction]
#[pyo3(signature = (calibration_json, calibration_name, sets, learn=true, folds=4))]
fn diagnose(
    py: Python<'_>,
    calibration_json: &str,
    calibration_name: &str,
    sets: Vec<Set>,
    learn: bool,
    folds: usize,
) -> PyResult<String> {
    let cal = calibration(calibration_json, calibration_name)?;
    let files = measurements(sets)?;
    let options = DiagnoseOptions {
        learn,
        folds,
        ..DiagnoseOptions::default()
    };
    let d = py
        .detach(|| robopost::diagnose(&cal, &files, &options))
        .map_err(value_error)?;
    to_text(&d)
}

/// Checks a calibration's JSON text; returns the robot's name.
#[pyfunction]
fn check_calibration(calibration_json: &str, calibration_name: &str) -> PyResult<String> {
    Ok(calibration(calibration_json, calibration_name)?.robot_name)
}

/// The module: the functions above.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(compensate, m)?)?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(check_calibration, m)?)?;
    m.add("PAPER_EFFECTS", robopost::PAPER_EFFECTS)?;
    Ok(())
}
