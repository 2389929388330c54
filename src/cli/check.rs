//! `robopost check FILE... [-c CAL.json]`: parse, simulate, report problems; writes nothing.

use super::Exit;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Programs to check (.src finds its .dat beside it; .dat alone is accepted).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Calibration: also simulate the motion and report unreachable or near-singular targets.
    #[arg(short = 'c', long = "cal")]
    pub cal: Option<PathBuf>,
}

pub fn run(_args: Args) -> Exit {
    eprintln!("robopost: check is not available in this build yet");
    Exit::Usage
}
