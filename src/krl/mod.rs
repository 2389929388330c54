//! The KUKA KRL front end, in three rooms: [`syntax`] reads `.src`/`.dat` files into a
//! lossless tree (and knows nothing of kinematics), [`interpret`] walks the tree as the
//! controller would and yields the language-neutral motion form (`motion`'s stops), and
//! [`rewrite`] places the compensated numbers back into the files, in their style; [`job`]
//! runs a KRL program's compensation end to end (load, walk, compensate, rewrite, report).
//! The reader's items keep their paths here (`krl::parse`, `krl::number`, `krl::Span` …).

pub mod interpret;
pub mod job;
pub mod rewrite;
pub mod syntax;

pub use syntax::*;
