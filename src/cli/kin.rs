//! `robopost fk` and `robopost ik`: check a pendant reading against the kinematics. `fk`
//! prints the nominal flange pose with S and T (and with `-c` the pose the calibrated model
//! predicts and the difference); `ik` prints every IK branch, or the one `--s`/`--t` select.

use std::path::PathBuf;

use nalgebra::Vector3;
use serde_json::json;

use super::Exit;
use crate::calibration;
use crate::kinematics::{
    forward, inverse, inverse_all, singularity, status_turn, Frame, IkError, IkSolution, Pose,
    RobotDescription, Select,
};
use crate::model::AxisState;

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct FkArgs {
    /// A1..A6 in degrees (KUKA convention).
    #[arg(num_args = 6, required = true, allow_negative_numbers = true)]
    pub axes: Vec<f64>,
    /// Also print the pose the calibrated model predicts (rotation directions unknown: the
    /// mean of both backlash branches).
    #[arg(short = 'c', long = "cal")]
    pub cal: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct IkArgs {
    /// X Y Z (mm) A B C (deg) of the flange in the robot base frame.
    #[arg(num_args = 6, required = true, allow_negative_numbers = true)]
    pub pose: Vec<f64>,
    /// Status S (selects the configuration): decimal (`6`) or binary (`'B110'`, `B110`).
    #[arg(long, value_parser = parse_bits)]
    pub s: Option<u8>,
    /// Turn T (selects among ±360° variants): decimal (`34`) or binary (`'B100010'`).
    #[arg(long, value_parser = parse_bits)]
    pub t: Option<u8>,
    /// Take the robot description (links, limits) from this calibration file instead of the
    /// built-in KR 30 HA; the IK stays nominal.
    #[arg(short = 'c', long = "cal")]
    pub cal: Option<PathBuf>,
    #[arg(long)]
    pub json: bool,
}

/// A KRL status/turn literal: `6`, `'B110'`, `B110` (quotes and case optional).
pub fn parse_bits(text: &str) -> Result<u8, String> {
    let t = text.trim().trim_matches('\'');
    let parsed = match t.strip_prefix(['B', 'b']) {
        Some(bits) if !bits.is_empty() && bits.chars().all(|c| c == '0' || c == '1') => {
            u8::from_str_radix(bits, 2)
        }
        Some(_) => return Err(format!("`{text}` is not a binary literal like 'B010'")),
        None => t.parse::<u8>(),
    };
    parsed.map_err(|_| format!("`{text}` is not a number 0..255 or a binary literal like 'B010'"))
}

fn axes_of(values: &[f64]) -> [f64; 6] {
    std::array::from_fn(|i| values[i])
}

/// `B010`-style rendering of the low `width` bits.
fn bits(value: u8, width: usize) -> String {
    format!("'B{value:0width$b}'")
}

/// `value` with `decimals` digits, without the sign of a value that rounds to zero.
fn fixed(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

/// [`fixed`] with an explicit `+` on non-negative values.
fn signed(value: f64, decimals: usize) -> String {
    let text = fixed(value, decimals);
    if text.starts_with('-') {
        text
    } else {
        format!("+{text}")
    }
}

fn pose_line(p: &Pose) -> String {
    format!(
        "{{X {}, Y {}, Z {}, A {}, B {}, C {}}}",
        fixed(p.x, 4),
        fixed(p.y, 4),
        fixed(p.z, 4),
        fixed(p.a, 5),
        fixed(p.b, 5),
        fixed(p.c, 5)
    )
}

fn pose_json(p: &Pose) -> serde_json::Value {
    json!({ "x": p.x, "y": p.y, "z": p.z, "a": p.a, "b": p.b, "c": p.c })
}

/// Notes on stderr about axes outside their limits or near a singularity.
fn axis_notes(robot: &RobotDescription, axes: &[f64; 6]) {
    for (i, (a, [lo, hi])) in axes.iter().zip(robot.limits_deg).enumerate() {
        if *a < lo || *a > hi {
            eprintln!("note: A{} = {a} is outside its limits [{lo}, {hi}]", i + 1);
        }
    }
    if let Some(s) = singularity(robot, axes) {
        eprintln!("note: near the {s}");
    }
}

/// The six numbers of the command line, or a usage error naming a non-finite one.
fn six_finite(command: &str, values: &[f64]) -> Result<[f64; 6], Exit> {
    match values.iter().find(|a| !a.is_finite()) {
        Some(bad) => {
            eprintln!("error: {command}: {bad} is not a finite number");
            Err(Exit::Usage)
        }
        None => Ok(axes_of(values)),
    }
}

/// The calibration of `-c`, if given; an unreadable or invalid file is a usage error.
fn load_calibration(path: Option<&PathBuf>) -> Result<Option<calibration::Calibration>, Exit> {
    path.map(|path| {
        calibration::load(path).map_err(|e| {
            eprintln!("error: {e}");
            Exit::Usage
        })
    })
    .transpose()
}

pub fn run_fk(args: FkArgs) -> Exit {
    let (axes, cal) = match (
        six_finite("fk", &args.axes),
        load_calibration(args.cal.as_ref()),
    ) {
        (Ok(axes), Ok(cal)) => (axes, cal),
        (Err(exit), _) | (_, Err(exit)) => return exit,
    };
    let robot = cal
        .as_ref()
        .map_or_else(RobotDescription::kr30ha, |c| c.model_ref().robot);
    let nominal_flange = forward(&robot, &axes);
    let nominal = nominal_flange.to_pose();
    let (s, t) = status_turn(&robot, &axes);
    let model = cal.as_ref().map(|c| {
        let flange = c.model_ref().flange_pose(&AxisState::new(axes));
        (flange, Difference::between(&nominal_flange, &flange))
    });
    if args.json {
        let mut out = pose_json(&nominal);
        out["s"] = json!(s);
        out["t"] = json!(t);
        if let Some((flange, d)) = &model {
            out["model"] = pose_json(&flange.to_pose());
            out["difference"] = json!({
                "x": d.offset.x, "y": d.offset.y, "z": d.offset.z,
                "distance_um": d.offset.norm() * 1000.0,
                "rotation_deg": d.rotation_deg,
            });
        }
        super::outln!("{out:#}");
    } else {
        super::outln!("nominal  {}", pose_line(&nominal));
        super::outln!("         S {s} {}  T {t} {}", bits(s, 3), bits(t, 6));
        if let (Some((flange, d)), Some(path)) = (&model, &args.cal) {
            super::outln!("model    {}", pose_line(&flange.to_pose()));
            super::outln!(
                "         ({}; rotation directions unknown: mean of both branches)",
                path.display()
            );
            super::outln!(
                "model − nominal: dX {}  dY {}  dZ {} mm, |d| {:.1} µm, rotation {:.5}°",
                signed(d.offset.x, 4),
                signed(d.offset.y, 4),
                signed(d.offset.z, 4),
                d.offset.norm() * 1000.0,
                d.rotation_deg
            );
        }
        axis_notes(&robot, &axes);
    }
    Exit::Success
}

/// Model minus nominal: flange position offset (mm, base frame) and rotation angle (deg).
struct Difference {
    offset: Vector3<f64>,
    rotation_deg: f64,
}

impl Difference {
    fn between(nominal: &Frame, model: &Frame) -> Difference {
        let (n, m) = (nominal.to_isometry().rotation, model.to_isometry().rotation);
        Difference {
            offset: model.position - nominal.position,
            rotation_deg: n.angle_to(&m).to_degrees(),
        }
    }
}

/// One printed IK row: the solution and, for a singular configuration, what is undefined.
struct Row {
    solution: IkSolution,
    singular: Option<String>,
}

/// Every solution, plus the configurations that are singular resolved as the controller
/// does by default (`$SINGUL_POS[] = 0`: the undefined A1 or A4 at 0°).
fn all_rows(robot: &RobotDescription, flange: &Frame) -> Result<Vec<Row>, IkError> {
    let all = inverse_all(robot, flange);
    let mut rows: Vec<Row> = all
        .as_ref()
        .map(|v| {
            v.iter()
                .map(|&solution| Row {
                    solution,
                    singular: None,
                })
                .collect()
        })
        .unwrap_or_default();
    for s in 0..8u8 {
        if rows.iter().any(|r| r.solution.s == s) {
            continue;
        }
        if let Err(IkError::Singular {
            kind,
            distance_deg_or_mm,
        }) = inverse(robot, flange, Select::Status { s, t: None })
        {
            let near = Select::StatusNearest { s, near: [0.0; 6] };
            if let Ok(solution) = inverse(robot, flange, near) {
                let at = rows.partition_point(|r| r.solution.s < s);
                let why = format!(
                    "{kind}, {} {} from it",
                    fixed(distance_deg_or_mm, 4),
                    kind.unit()
                );
                rows.insert(
                    at,
                    Row {
                        solution,
                        singular: Some(why),
                    },
                );
            }
        }
    }
    match all {
        Err(e) if rows.is_empty() => Err(e),
        _ => Ok(rows),
    }
}

fn selected_row(
    robot: &RobotDescription,
    flange: &Frame,
    s: u8,
    t: Option<u8>,
) -> Result<Row, IkError> {
    match inverse(robot, flange, Select::Status { s, t }) {
        Ok(solution) => Ok(Row {
            solution,
            singular: None,
        }),
        Err(IkError::Singular {
            kind,
            distance_deg_or_mm,
        }) => {
            let near = Select::StatusNearest { s, near: [0.0; 6] };
            let solution = inverse(robot, flange, near)?;
            if t.is_some_and(|t| t != solution.t) {
                return Err(IkError::Singular {
                    kind,
                    distance_deg_or_mm,
                });
            }
            let why = format!(
                "{kind}, {} {} from it",
                fixed(distance_deg_or_mm, 4),
                kind.unit()
            );
            Ok(Row {
                solution,
                singular: Some(why),
            })
        }
        Err(e) => Err(e),
    }
}

pub fn run_ik(args: IkArgs) -> Exit {
    let (values, cal) = match (
        six_finite("ik", &args.pose),
        load_calibration(args.cal.as_ref()),
    ) {
        (Ok(values), Ok(cal)) => (values, cal),
        (Err(exit), _) | (_, Err(exit)) => return exit,
    };
    let robot = cal.map_or_else(RobotDescription::kr30ha, |c| c.model_ref().robot);
    let flange = Frame::from_kuka(&Pose::from_array(values));
    let rows = match args.s {
        Some(s) if s > 7 => {
            eprintln!("error: --s {s} has bits above bit 2 (S is 0..7)");
            return Exit::Usage;
        }
        Some(s) => selected_row(&robot, &flange, s, args.t).map(|r| vec![r]),
        None => all_rows(&robot, &flange).map(|rows| match args.t {
            Some(t) => rows.into_iter().filter(|r| r.solution.t == t).collect(),
            None => rows,
        }),
    };
    let rows = match rows {
        Ok(rows) if rows.is_empty() => {
            eprintln!("error: no solution with T {}", args.t.unwrap_or_default());
            return Exit::Rejected;
        }
        Ok(rows) => rows,
        Err(e) => {
            eprintln!("error: {e}");
            return Exit::Rejected;
        }
    };
    if args.json {
        let solutions: Vec<_> = rows
            .iter()
            .map(|r| {
                let mut v = json!({
                    "axes": r.solution.axes_deg, "s": r.solution.s, "t": r.solution.t,
                });
                if let Some(why) = &r.singular {
                    v["singular"] = json!(why);
                }
                v
            })
            .collect();
        super::outln!("{:#}", json!({ "solutions": solutions }));
        return Exit::Success;
    }
    super::outln!(
        "{:<12} {:<14} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "S",
        "T",
        "A1",
        "A2",
        "A3",
        "A4",
        "A5",
        "A6"
    );
    for r in &rows {
        let sol = &r.solution;
        let a = sol.axes_deg;
        super::outln!(
            "{:<12} {:<14} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}{}",
            format!("{} {}", sol.s, bits(sol.s, 3)),
            format!("{} {}", sol.t, bits(sol.t, 6)),
            fixed(a[0], 4),
            fixed(a[1], 4),
            fixed(a[2], 4),
            fixed(a[3], 4),
            fixed(a[4], 4),
            fixed(a[5], 4),
            r.singular
                .as_ref()
                .map(|w| format!("  singular: {w}"))
                .unwrap_or_default()
        );
    }
    if rows.iter().any(|r| r.singular.is_some()) {
        eprintln!(
            "note: in a singular configuration the undefined axis (A4 at A5 = 0, A1 with the \
             wrist point on the A1 axis) is shown at 0°, as the controller moves it by default \
             ($SINGUL_POS[] = 0)"
        );
    }
    Exit::Success
}

#[cfg(test)]
mod tests {
    use super::parse_bits;

    #[test]
    fn rounded_zero_has_no_sign() {
        assert_eq!(super::fixed(-0.00001, 4), "0.0000");
        assert_eq!(super::fixed(-0.0, 2), "0.00");
        assert_eq!(super::fixed(-0.5, 1), "-0.5");
    }

    #[test]
    fn status_literals() {
        assert_eq!(parse_bits("6"), Ok(6));
        assert_eq!(parse_bits("'B110'"), Ok(6));
        assert_eq!(parse_bits("b010"), Ok(2));
        assert_eq!(parse_bits("B100010"), Ok(34));
        assert!(parse_bits("B12").is_err());
        assert!(parse_bits("'B'").is_err());
        assert!(parse_bits("-1").is_err());
        assert!(parse_bits("256").is_err());
    }
}
