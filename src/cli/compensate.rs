//! `robopost IN.src -c CAL.json -o OUT.src`: compensate one program.

use super::Exit;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input program (.src; its .dat beside it is used too), or `-` for stdin.
    pub input: PathBuf,
    /// Calibration file.
    #[arg(short = 'c', long = "cal")]
    pub cal: PathBuf,
    /// Output program, or `-` for stdout.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
}

pub fn run(_args: Args) -> Exit {
    eprintln!("robopost: compensation is not available in this build yet");
    Exit::Usage
}
