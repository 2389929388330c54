//! `robopost fk` and `robopost ik`: check a pendant reading against the kinematics.

use super::Exit;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct FkArgs {
    /// A1..A6 in degrees (KUKA convention).
    #[arg(num_args = 6, required = true, allow_negative_numbers = true)]
    pub axes: Vec<f64>,
    /// Also print the pose the calibrated model predicts.
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
    /// Status bits S (selects the branch).
    #[arg(long)]
    pub s: Option<u8>,
    /// Turn bits T (selects among ±360° variants).
    #[arg(long)]
    pub t: Option<u8>,
    #[arg(long)]
    pub json: bool,
}

pub fn run_fk(_args: FkArgs) -> Exit {
    eprintln!("robopost: fk is not available in this build yet");
    Exit::Usage
}

pub fn run_ik(_args: IkArgs) -> Exit {
    eprintln!("robopost: ik is not available in this build yet");
    Exit::Usage
}
