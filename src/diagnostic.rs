//! User-facing errors with file:line:col, the offending source line and a hint.
