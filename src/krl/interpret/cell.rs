//! The robot's cell as the context of a program run: a backup or project tree (`KRC/R1/…` as
//! the controller and WorkVisual lay it out, or any folder) and the data lists and modules
//! given one by one for a partial backup. It knows where `$config.dat` is, which data lists
//! declare `GLOBAL` data every program sees (`DEFDAT name PUBLIC`), which module defines each
//! routine a program may call (a module's first routine and its `GLOBAL DEF`/`DEFFCT`,
//! whatever the module's file name), and where the robot's machine data are
//! (`$machine.dat`). Scanned once, by reading lines (not parsing); the files a program needs
//! are parsed when the program is loaded (see `workspace`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::kinematics::RobotDescription;

/// Files of a cell by what they hold.
#[derive(Clone, Debug, Default)]
pub struct Cell {
    /// `$config.dat` (the one under `R1` when a tree holds several).
    pub config: Option<PathBuf>,
    /// Data lists with declarations every program sees: system data lists (`DEFDAT $…`)
    /// and `PUBLIC` data lists with `GLOBAL` declarations, `$config.dat` not included.
    pub data: Vec<PathBuf>,
    /// Routine name (upper case) → the modules (`.src`, `.sub`) defining it globally.
    pub routines: HashMap<Vec<u8>, Vec<PathBuf>>,
    /// `$machine.dat` of the robot (under `R1/Mada` when a tree holds several).
    pub machine: Option<PathBuf>,
    /// Files read while scanning.
    pub scanned: usize,
    /// Files of a kind the cell takes more than one of where it uses one (several
    /// `$config.dat`), with the one chosen: said once by whoever loads the cell.
    pub notes: Vec<String>,
}

/// A file of the cell that could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{}: {source}", path.display())]
pub struct ScanError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

fn is_ext(p: &Path, exts: &[&str]) -> bool {
    p.extension()
        .is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

fn named(p: &Path, name: &str) -> bool {
    p.file_name()
        .is_some_and(|n| n.to_string_lossy().eq_ignore_ascii_case(name))
}

/// Whether `p` lies under a directory named `R1` (the robot's own tree in a backup).
fn under_r1(p: &Path) -> bool {
    p.components()
        .any(|c| c.as_os_str().to_string_lossy().eq_ignore_ascii_case("R1"))
}

/// The code of a line: without leading blanks and its comment.
fn code(line: &[u8]) -> &[u8] {
    let start = line
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(line.len());
    let line = &line[start..];
    let end = line.iter().position(|&b| b == b';').unwrap_or(line.len());
    line[..end].trim_ascii_end()
}

/// The next word of `s` (letters, digits, `_`, `$`) upper-cased, and the rest after blanks.
fn word(s: &[u8]) -> (Vec<u8>, &[u8]) {
    let n = s
        .iter()
        .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_' || **b == b'$')
        .count();
    let rest = s[n..].trim_ascii_start();
    (s[..n].to_ascii_uppercase(), rest)
}

/// The routines a module defines for callers outside it: its first routine (the module's
/// main routine, called by its name) and every `GLOBAL DEF`/`GLOBAL DEFFCT`.
pub fn module_routines(src: &[u8]) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let mut first = true;
    for line in src.split(|&b| b == b'\n') {
        let (w, rest) = word(code(line));
        let (global, w, rest) = if w == b"GLOBAL" {
            let (w2, rest2) = word(rest);
            (true, w2, rest2)
        } else {
            (false, w, rest)
        };
        let name = match w.as_slice() {
            b"DEF" => word(rest).0,
            // `DEFFCT TYPE name(` — the type may carry a size (`CHAR[15]`).
            b"DEFFCT" => {
                let (_, after_type) = word(rest);
                let after_type = match after_type.first() {
                    Some(b'[') => after_type
                        .iter()
                        .position(|&b| b == b']')
                        .map_or(after_type, |p| after_type[p + 1..].trim_ascii_start()),
                    _ => after_type,
                };
                word(after_type).0
            }
            _ => continue,
        };
        if name.is_empty() {
            continue;
        }
        if global || first {
            out.push(name);
        }
        first = false;
    }
    out
}

/// What a data list shares with every program: all its declarations (a system data list,
/// `DEFDAT $…`), its `GLOBAL` ones (`DEFDAT name PUBLIC` with some), or nothing.
fn data_list_shares(src: &[u8]) -> bool {
    let mut public = false;
    for line in src.split(|&b| b == b'\n') {
        let (w, rest) = word(code(line));
        match w.as_slice() {
            b"DEFDAT" => {
                let (name, rest) = word(rest);
                if name.starts_with(b"$") {
                    return true;
                }
                public = word(rest).0 == b"PUBLIC";
                if !public {
                    return false;
                }
            }
            b"GLOBAL" if public => return true,
            _ => {}
        }
    }
    false
}

impl Cell {
    /// A cell of the tree under `root` (if any) and of the files given one by one (data
    /// lists, `$config.dat`, modules), those taking precedence.
    pub fn scan(root: Option<&Path>, files: &[PathBuf]) -> Result<Cell, ScanError> {
        let mut cell = Cell::default();
        let mut found = Vec::new();
        if let Some(r) = root {
            walk(r, &mut found).map_err(|source| ScanError {
                path: r.to_path_buf(),
                source,
            })?;
            found.sort();
        }
        // Files given by hand first: they win where names collide.
        let given: Vec<PathBuf> = files.to_vec();
        let mut configs: Vec<PathBuf> = Vec::new();
        let mut machines: Vec<PathBuf> = Vec::new();
        for (by_hand, path) in given
            .iter()
            .map(|p| (true, p))
            .chain(found.iter().map(|p| (false, p)))
        {
            if named(path, "$config.dat") {
                configs.push(path.clone());
                continue;
            }
            if named(path, "$machine.dat") {
                machines.push(path.clone());
                continue;
            }
            let mut read = || {
                cell.scanned += 1;
                crate::input::read(path).map_err(|source| ScanError {
                    path: path.clone(),
                    source,
                })
            };
            if is_ext(path, &["src", "sub"]) {
                let bytes = read()?;
                for name in module_routines(&bytes) {
                    cell.routines.entry(name).or_default().push(path.clone());
                }
            } else if is_ext(path, &["dat"]) {
                let bytes = read()?;
                // A data list given by hand is always used; from the tree, when it shares.
                if by_hand || data_list_shares(&bytes) {
                    cell.data.push(path.clone());
                }
            }
        }
        let pick = |list: &[PathBuf], what: &str, notes: &mut Vec<String>| {
            let chosen = list
                .iter()
                .find(|p| files.contains(p))
                .or_else(|| list.iter().find(|p| under_r1(p)))
                .or(list.first())
                .cloned();
            if list.len() > 1 {
                if let Some(c) = &chosen {
                    notes.push(format!(
                        "{} files named {what} in the cell: using {}",
                        list.len(),
                        c.display()
                    ));
                }
            }
            chosen
        };
        let mut notes = Vec::new();
        cell.config = pick(&configs, "$config.dat", &mut notes);
        // The controller's machine data (`STEU/Mada`) do not describe the robot.
        let steu = |p: &Path| {
            p.components()
                .any(|c| c.as_os_str().to_string_lossy().eq_ignore_ascii_case("STEU"))
        };
        let robots: Vec<PathBuf> = machines
            .iter()
            .filter(|p| files.contains(p) || !steu(p))
            .cloned()
            .collect();
        cell.machine = pick(&robots, "$machine.dat", &mut notes);
        cell.notes = notes;
        Ok(cell)
    }

    /// The module defining routine `name` (upper case) nearest to `near` (the calling
    /// program's directory), or `None`.
    pub fn module_of(&self, name: &[u8], near: &Path) -> Option<&Path> {
        let list = self.routines.get(name)?;
        let near = near.canonicalize().unwrap_or_else(|_| near.to_path_buf());
        list.iter()
            .max_by_key(|p| {
                let dir = p
                    .parent()
                    .map(|d| d.canonicalize().unwrap_or_else(|_| d.to_path_buf()));
                // Most directory levels shared with the program; the first found on a tie.
                let shared = dir.map_or(0, |d| {
                    d.components()
                        .zip(near.components())
                        .take_while(|(a, b)| a == b)
                        .count()
                });
                (shared, std::cmp::Reverse(list.iter().position(|q| q == *p)))
            })
            .map(PathBuf::as_path)
    }

    /// Whether the cell holds nothing at all.
    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.config.is_none()
            && self.data.is_empty()
            && self.routines.is_empty()
            && self.machine.is_none()
    }
}

/// Why the machine data give no robot robopost can model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MachineDataError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A value the description needs is not there (`what`: `$LENGTH_A`, a software limit…).
    #[error("{}: no {what} in the machine data", path.display())]
    Missing { path: PathBuf, what: String },
    /// The machine data describe another kinematic family: `robot` is its `$TRAFONAME`,
    /// `why` the reason read from the data.
    #[error("{}: the robot {robot} is {why}: robopost models six-axis arms with a central wrist (the KUKA KR family of its calibration files)", path.display())]
    NotModelled {
        path: PathBuf,
        robot: String,
        why: String,
    },
}

/// The robot the machine data (`$machine.dat`) describe: its type (`$TRAFONAME`, without the
/// `#`) and its nominal description — `$LENGTH_A`, `$LENGTH_B`, the frames `$TIRORO` (base to
/// the A2 height), `$TX3P3` (A3 to the wrist point, with the wrist offset) and `$TFLWP` (wrist
/// point to flange), the software limits `$SOFTN_END`/`$SOFTP_END`. Refused with the reason
/// when they describe another kinematic family than the six-axis arm with a central wrist
/// robopost models (a palletiser's offset wrist, a special kinematic class).
pub fn machine_robot(path: &Path) -> Result<(String, RobotDescription), MachineDataError> {
    use crate::krl::{Expr, FileKind, StmtKind};
    let bytes = crate::input::read(path).map_err(|source| MachineDataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file = crate::krl::parse_recovering(&bytes, FileKind::Dat);
    let mut values: HashMap<Vec<u8>, &Expr> = HashMap::new();
    let mut limits = [[None::<f64>; 2]; 6];
    let mut name = None;
    let number = |e: &Expr| match e {
        Expr::Number(n) => Some(n.value),
        Expr::Unary(u) => match (&u.op, &u.operand) {
            (crate::krl::UnOp::Neg, Expr::Number(n)) => Some(-n.value),
            _ => None,
        },
        _ => None,
    };
    for st in file.statements() {
        match &st.kind {
            StmtKind::Decl(d) => {
                for v in &d.vars {
                    if let Some(e) = &v.init {
                        values.insert(file.text(v.name).to_ascii_uppercase(), e);
                    }
                }
            }
            StmtKind::Assign(a) => {
                let Some(p) = a.lhs.as_path() else { continue };
                let root = file.text(p.root).to_ascii_uppercase();
                let index = match p.access.as_slice() {
                    [crate::krl::Access::Index { items, .. }] => items
                        .first()
                        .and_then(|i| i.as_number())
                        .map(|n| n.value as usize),
                    _ => None,
                };
                match (root.as_slice(), index) {
                    (b"$TRAFONAME", _) => {
                        if let Expr::Str(s) = &a.rhs {
                            let t = file.text(*s);
                            name = Some(String::from_utf8_lossy(&t[1..t.len() - 1]).into_owned());
                        }
                    }
                    (b"$SOFTN_END" | b"$SOFTP_END", Some(i @ 1..=6)) => {
                        limits[i - 1][usize::from(root == b"$SOFTP_END")] = number(&a.rhs);
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }
    let missing = |what: &str| MachineDataError::Missing {
        path: path.to_path_buf(),
        what: what.to_string(),
    };
    let real = |key: &str| -> Result<f64, MachineDataError> {
        values
            .get(key.as_bytes())
            .and_then(|e| number(e))
            .ok_or_else(|| missing(key))
    };
    let member = |key: &str, m: &str| -> Result<f64, MachineDataError> {
        let agg = values
            .get(key.as_bytes())
            .and_then(|e| file.aggregate_of(e))
            .ok_or_else(|| missing(key))?;
        Ok(file
            .member(agg, m)
            .and_then(|x| number(&x.value))
            .unwrap_or(0.0))
    };
    let name = name
        .map(|n| n.trim_start_matches('#').trim().to_string())
        .unwrap_or_else(|| "the robot of the machine data".into());
    let refuse = |why: String| {
        Err(MachineDataError::NotModelled {
            path: path.to_path_buf(),
            robot: name.clone(),
            why,
        })
    };
    if let Some(Expr::Enum(k)) = values.get(&b"$KINCLASS"[..]).copied() {
        if !file.text(*k).eq_ignore_ascii_case(b"#STANDARD") {
            return refuse(format!("of kinematic class {}", file.text_lossy(*k)));
        }
    }
    if let Ok(n) = real("$NUM_AX") {
        if n != 6.0 {
            return refuse(format!("a {n}-axis robot"));
        }
    }
    for (dh, alpha) in [("$DH_4", 90.0), ("$DH_5", -90.0)] {
        let (a, d, al) = (
            member(dh, "DHART_A")?,
            member(dh, "DHART_D")?,
            member(dh, "DHART_ALPHA")?,
        );
        if a != 0.0 || d != 0.0 || al != alpha {
            return refuse(format!(
                "not one: its wrist has an offset ({dh} = A {a}, D {d}, ALPHA {al}; a palletiser?)"
            ));
        }
    }
    let tx3p3: Vec<f64> = ["X", "Y", "Z", "A", "B", "C"]
        .iter()
        .map(|m| member("$TX3P3", m))
        .collect::<Result<_, _>>()?;
    if tx3p3[1] != 0.0 || tx3p3[3] != 0.0 || tx3p3[4] != 90.0 || tx3p3[5] != 0.0 {
        return refuse(format!("not one: its forearm frame $TX3P3 is {tx3p3:?}"));
    }
    let mut limits_deg = [[0.0; 2]; 6];
    for (k, [lo, hi]) in limits.iter().enumerate() {
        let (Some(lo), Some(hi)) = (lo, hi) else {
            return Err(missing(&format!("software limit of A{}", k + 1)));
        };
        limits_deg[k] = [*lo, *hi];
    }
    let robot = RobotDescription {
        links: crate::kinematics::Links {
            l1x: real("$LENGTH_A")?,
            l1z: member("$TIRORO", "Z")?,
            l2: real("$LENGTH_B")?,
            l3z: tx3p3[2],
            l4x: tx3p3[0],
            l5x: member("$TFLWP", "Z")?,
        },
        limits_deg,
        ..RobotDescription::kr30ha()
    };
    Ok((
        name,
        RobotDescription {
            gravity: None,
            ..robot
        },
    ))
}

/// Every file under `dir`, recursively (symbolic links to directories not followed).
fn walk(dir: &Path, out: &mut Vec<PathBuf>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let p = e.path();
        let ty = e.file_type()?;
        if ty.is_dir() {
            walk(&p, out)?;
        } else if ty.is_file() || (ty.is_symlink() && p.is_file()) {
            out.push(p);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routines_a_module_offers() {
        let src = b"&ACCESS RVP\r\nDEF main_prog( )\r\n  PTP HOME\r\nEND\r\n\r\nDEF local_one()\r\nEND\r\n  GLOBAL DEF SetFrames (b:IN, t:IN) ; sets $BASE\r\nEND\r\nglobal deffct frame Offset(d:IN)\r\nENDFCT\r\nGLOBAL DEFFCT CHAR[15] K_ADDR(BASE_NO :IN)\r\nENDFCT\r\n; GLOBAL DEF commented()\r\n";
        let names: Vec<String> = module_routines(src)
            .into_iter()
            .map(|n| String::from_utf8(n).unwrap())
            .collect();
        assert_eq!(names, ["MAIN_PROG", "SETFRAMES", "OFFSET", "K_ADDR"]);
    }

    #[test]
    fn data_lists_that_share() {
        assert!(data_list_shares(b"DEFDAT $CONFIG\r\nINT X\r\nENDDAT"));
        assert!(data_list_shares(
            b"&ACCESS RV\r\nDEFDAT cell_data PUBLIC\r\nDECL INT a\r\nGLOBAL E6POS P={X 1}\r\nENDDAT"
        ));
        assert!(!data_list_shares(
            b"DEFDAT cell_data PUBLIC\r\nDECL INT a\r\nENDDAT"
        ));
        assert!(!data_list_shares(b"DEFDAT prog\r\nGLOBAL INT a\r\nENDDAT"));
    }
}
