//! Nominal descriptions of common KUKA six-axis robots, shipped as calibration files without
//! error effects (`calibrations/*-nominal.json`) and built into the binary, so that a robot
//! can be named on the command line (`--robot "KR 16"`) wherever it is run from. A name is
//! matched ignoring case, blanks, `-` and `_` (`"kr16-2"`, `"KR 16-2"`), against the
//! robot's name and its aliases (`"KR 16"`, the models of the same geometry).

use std::path::Path;

use super::{CalError, Calibration};

/// One shipped robot.
#[derive(Clone, Copy, Debug)]
pub struct Robot {
    /// The name its file gives (`KR 16-2`).
    pub name: &'static str,
    /// Other names of the same geometry.
    pub aliases: &'static [&'static str],
    /// The file under `calibrations/`.
    pub file: &'static str,
    json: &'static str,
}

macro_rules! robot {
    ($name:literal, [$($alias:literal),*], $file:literal) => {
        Robot {
            name: $name,
            aliases: &[$($alias),*],
            file: $file,
            json: include_str!(concat!("../../calibrations/", $file)),
        }
    };
}

/// Every shipped robot.
pub const ROBOTS: &[Robot] = &[
    robot!("KR 30 HA", ["KR 30-3", "KR 30"], "kr30ha-nominal.json"),
    robot!(
        "KR 6 R700 sixx",
        ["KR 6 R700", "KR 6 R700-2"],
        "kr6r700sixx-nominal.json"
    ),
    robot!(
        "KR 6 R900 sixx",
        ["KR 6 R900", "KR 6 R900 C4SR"],
        "kr6r900sixx-nominal.json"
    ),
    robot!("KR 10 R1420", [], "kr10r1420-nominal.json"),
    robot!("KR 16-2", ["KR 16", "KR 16 C2"], "kr16-2-nominal.json"),
    robot!(
        "KR 120 R2500 pro",
        ["KR 120 R2500"],
        "kr120r2500pro-nominal.json"
    ),
    robot!(
        "KR 120 R2700-2",
        ["KR 210 R2700-2"],
        "kr120r2700-2-nominal.json"
    ),
    robot!(
        "KR 210 R2700 prime",
        [
            "KR 210 R2700",
            "KR 120 R2700 extra",
            "KR 120 R2700 extra HA"
        ],
        "kr210r2700prime-nominal.json"
    ),
    robot!("KR 150 R3100-2", [], "kr150r3100-2-nominal.json"),
];

/// The name as compared: upper case without blanks, `-`, `_`.
fn key(name: &str) -> String {
    name.chars()
        .filter(|c| !matches!(c, ' ' | '-' | '_' | '\t'))
        .flat_map(char::to_uppercase)
        .collect()
}

impl Robot {
    /// The robot's nominal calibration (no error effects).
    pub fn calibration(&self) -> Calibration {
        super::parse(self.json, Path::new(self.file)).expect("a shipped calibration is valid")
    }

    fn answers_to(&self, name: &str) -> bool {
        let k = key(name);
        std::iter::once(self.name)
            .chain(self.aliases.iter().copied())
            .any(|n| key(n) == k)
    }
}

/// The shipped robot of that name or alias.
pub fn by_name(name: &str) -> Option<&'static Robot> {
    ROBOTS.iter().find(|r| r.answers_to(name))
}

/// Why `--robot NAME|FILE` names no robot.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ResolveError {
    /// Neither a shipped robot's name or alias nor a file; `known` are the shipped names.
    #[error("`{arg}` is neither a robot robopost knows ({}) nor a calibration file", known.join(", "))]
    Unknown {
        arg: String,
        known: Vec<&'static str>,
    },
    /// A file that is not a valid calibration.
    #[error(transparent)]
    Calibration(#[from] CalError),
}

/// `--robot NAME|FILE`: a shipped robot by name, or a calibration file (its robot). The
/// error lists the names known.
pub fn resolve(arg: &str) -> Result<Calibration, ResolveError> {
    if let Some(r) = by_name(arg) {
        return Ok(r.calibration());
    }
    let path = Path::new(arg);
    if path.is_file() {
        return Ok(super::load(path)?);
    }
    Err(ResolveError::Unknown {
        arg: arg.to_string(),
        known: ROBOTS.iter().map(|r| r.name).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_robot_loads_and_answers_to_its_names() {
        for r in ROBOTS {
            let cal = r.calibration();
            assert_eq!(cal.robot_name, r.name, "{}", r.file);
            assert!(
                cal.model_ref().effects().is_empty(),
                "{} is nominal",
                r.file
            );
            for n in std::iter::once(r.name).chain(r.aliases.iter().copied()) {
                assert_eq!(by_name(n).map(|x| x.name), Some(r.name), "{n}");
            }
        }
        assert_eq!(by_name("kr16-2").unwrap().name, "KR 16-2");
        assert_eq!(by_name("kr 16").unwrap().name, "KR 16-2");
        assert!(by_name("KR 1000 titan").is_none());
        match resolve("KR 1000 titan") {
            Err(e @ ResolveError::Unknown { .. }) => {
                let ResolveError::Unknown { arg, known } = &e else {
                    unreachable!()
                };
                assert_eq!(arg, "KR 1000 titan");
                assert!(known.contains(&"KR 16-2"), "{known:?}");
                assert!(e.to_string().contains("KR 16-2"), "{e}");
            }
            other => panic!("{other:?}"),
        }
    }
}
