//! KUKA KRL front end (filled in by the parser work).
