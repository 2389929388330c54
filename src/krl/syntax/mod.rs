//! The KRL front end's reader: a lossless parser of `.src` and `.dat` files (nom over bytes, never
//! decoding), the syntax tree it builds, and byte edits to rewrite a program. Every byte of a
//! file belongs to a statement or to trivia, so `parse(b)?.emit() == b` for any input; lines
//! the parser does not understand are kept as opaque statements. Malformed motions,
//! declarations and aggregates are errors with a line, column and hint. This module knows
//! nothing of kinematics (`tests/seam.rs` holds it to that: it names nothing of the crate but
//! itself, the diagnostics and the input reader): it only says what the program says, with
//! the byte span of every number so another module can compute new values and write them
//! back with [`edit`]. Its items are re-exported at `krl::` (`krl::parse`, `krl::Span` …).
//!
//! # How to walk a program
//!
//! ```
//! use robopost::krl::{self, Expr, FileKind, StmtKind, Symbols};
//!
//! let src = b"DEF demo()\r\n\
//!   $BASE = BASE_DATA[1]\r\n\
//!   PTP XHOME\r\n\
//!   FOR i = 1 TO 2\r\n\
//!     LIN {X 100.0, Y -2.5E+01, Z .25} C_DIS ; cut\r\n\
//!   ENDFOR\r\n\
//!   CIRC XAUX, XEND, CA 90\r\n\
//! END";
//! let dat = b"DEFDAT demo\r\nDECL E6POS XHOME={X 1,Y 2,Z 3,A 0,B 90,C 0}\r\nENDDAT\r\n";
//! let program = krl::parse(src, FileKind::Src).unwrap();
//! let data = krl::parse(dat, FileKind::Dat).unwrap();
//! assert_eq!(program.emit(), src); // lossless
//!
//! // Statements in execution-text order, nested bodies included (FOR, IF, SPLINE blocks…).
//! let symbols = Symbols::new(&[&data, &program]);
//! let mut seen = Vec::new();
//! for stmt in program.statements() {
//!     match &stmt.kind {
//!         StmtKind::Motion(id) => {
//!             let m = program.motion(*id);
//!             let target = match &m.target {
//!                 // An inline aggregate: every member's number with its span.
//!                 Expr::Aggregate(_, aid) => {
//!                     let a = program.aggregate(*aid);
//!                     let y = program.member_number(a, "Y").unwrap();
//!                     assert_eq!(program.text(y.span()), b"-2.5E+01");
//!                     format!("inline Y={}", y.value)
//!                 }
//!                 // A variable: resolve it through the .dat.
//!                 Expr::Path(p) if p.is_simple() => {
//!                     let sym = symbols.get(program.text(p.root));
//!                     format!("variable, declared: {}", sym.is_some())
//!                 }
//!                 other => format!("{:?}", other.span()),
//!             };
//!             seen.push(format!("L{} {} {}", stmt.line, m.kind.keyword(), target));
//!         }
//!         StmtKind::For(Some(f)) => seen.push(format!("L{} FOR {}", stmt.line, program.text_lossy(f.var))),
//!         _ => {}
//!     }
//! }
//! assert_eq!(seen, [
//!     "L3 PTP variable, declared: true",
//!     "L4 FOR i",
//!     "L5 LIN inline Y=-25",
//!     "L7 CIRC variable, declared: false",
//! ]);
//!
//! // Rewrite one number in the original style; everything else is copied byte for byte.
//! let (_, lin) = program.motions().nth(1).unwrap();
//! let target = program.aggregate_of(&lin.target).unwrap();
//! let x = program.member_number(target, "X").unwrap();
//! let mut edits = krl::Edits::new();
//! edits.replace(x.span(), krl::number::format_like(program.text(x.span()), 100.0374, 3));
//! let out = edits.apply(program.source()).unwrap();
//! assert!(out.windows(17).any(|w| w == b"LIN {X 100.037, Y"));
//! ```
//!
//! Long programs: [`parse_streaming`] leaves the long plain stretches of the main routine (CAM
//! motions to literal positions) out of the tree as [`StreamedRun`]s, each parsed later window
//! by window with [`SourceFile::window`] (see [`stream`]).
//!
//! Inline forms: `program.inline_form(stmt)` gives the ILF fold a statement sits in, with the
//! point name, velocity, motion data and tool/base of the form (`IlfMotion`), and the names
//! KUKA gives their `.dat` variables (`position_var` → `XP1`, `frame_data_var` → `FP1`,
//! `motion_data_var` → `PPDAT1`/`LCPDAT1`).

pub mod decl;
// The tree printed for the parser's tests and fuzz targets.
#[cfg(any(test, feature = "internals"))]
pub mod dump;
pub mod edit;
pub mod error;
pub mod expr;
pub mod fold;
mod lex;
mod memory;
pub mod motion;
mod nodes;
pub mod number;
mod plain;
pub mod program;
pub mod sniff;
pub mod span;
pub mod stmt;
pub mod stream;
pub mod symbols;
pub mod tree;
mod trivia;

pub use decl::{ParamMode, RoutineHeader, TypeKind};
pub use edit::{apply, Edit, EditError};
pub use error::{ParseError, Severity};
pub use expr::{Access, Aggregate, BinOp, Call, Expr, Number, Path, UnOp};
pub use motion::{Motion, MotionKind, RelFrameKind, WithItem};
pub use nodes::RawMember;
pub use sniff::not_krl;
pub use span::Span;
pub use stmt::{ArmKind, Stmt, StmtKind};
pub use stream::{StreamOptions, StreamedRun};
pub use symbols::{Symbol, Symbols};
pub use tree::{
    parse, parse_recovering, parse_recovering_owned, parse_streaming, FileKind, SourceFile,
};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use {
    decl::{Decl, DeclVar, Dims, Param, TypeRef},
    edit::Edits,
    error::Problem,
    expr::Member,
    fold::{Fold, FoldId, Ilf, IlfFrame, IlfMotion, IlfVelocity},
    motion::{Approx, ApproxKind, Approxes, RelFrame},
    nodes::{AggregateId, Members, MotionId, RawMembers},
    program::{LoadError, Program},
    span::LineIndex,
    stmt::{Action, Arm, Assign, Block, Clause, Directive, For},
    tree::{Stats, TileKind},
};

/// The `.dat` beside a `.src` (same stem, `.dat` or `.DAT`), if there is anything of that
/// name: a directory or a broken link there is then an error when it is read, not a program
/// silently without its data list.
pub fn companion_dat(src: &std::path::Path) -> Option<std::path::PathBuf> {
    if FileKind::from_path(src) == FileKind::Dat {
        return None;
    }
    ["dat", "DAT", "Dat"]
        .iter()
        .map(|e| src.with_extension(e))
        .find(|p| std::fs::symlink_metadata(p).is_ok())
}
