//! The validation programs with the tracker's reflector as the calibration identified it.

use std::path::Path;

use robopost::model::Model;

/// A copy (in `dir`, with its `.dat`) of the program at `src` whose tool is the measurement
/// target as `model` identified it: after a calibration the tracker's reflector is where the
/// calibration found it (the data tell the reflector's offset on the flange only together with
/// the flange's own error, so the nominal nest drawing is not it), and a program that moves the
/// reflector says so in its `$TOOL`.
pub fn with_identified_tool(src: &Path, model: &Model, dir: &Path) -> std::path::PathBuf {
    let t = model.target_mm;
    let text = std::fs::read_to_string(src).unwrap();
    // The fixtures spell the nominal tool in two ways.
    let spellings = [
        ("$TOOL={X -120.0,Y -80.0,Z 180.0,", ","),
        ("$TOOL = {X -120.0, Y -80.0, Z 180.0,", ", "),
    ];
    let (nominal, sep) = spellings
        .iter()
        .find(|(n, _)| text.contains(n))
        .unwrap_or_else(|| panic!("{}: no nominal $TOOL", src.display()));
    let tooled = text.replace(
        nominal,
        &format!("$TOOL={{X {:.4}{sep}Y {:.4}{sep}Z {:.4},", t.x, t.y, t.z),
    );
    let out = dir.join(src.file_name().unwrap());
    std::fs::write(&out, tooled).unwrap();
    std::fs::copy(src.with_extension("dat"), out.with_extension("dat")).unwrap();
    out
}
