//! The KUKA status S and turn T of axis angles (MODEL.md), for checking that compensation keeps
//! a target's configuration. S bit 0: wrist point behind the A1 axis; bit 1: A3 ≥ φ =
//! atan2(l3z, l4x); bit 2: A5 < 0. T bit i: axis i+1 < 0.

use crate::kinematics::RobotDescription;
use crate::model::chain::ChainFrames;
use crate::model::ChainErrors;

pub fn status_turn(robot: &RobotDescription, axes: &[f64; 6]) -> (u8, u8) {
    let frames = ChainFrames::new(robot, axes, &ChainErrors::default());
    let wrist = frames.axis_origin(5);
    let (s1, c1) = axes[0].to_radians().sin_cos();
    // The wrist point in the frame turned with A1 (A1 turns about −Z).
    let x_a1 = c1 * wrist.x - s1 * wrist.y;
    let phi = robot.links.l3z.atan2(robot.links.l4x).to_degrees();
    let mut s = 0u8;
    if x_a1 < 0.0 {
        s |= 1;
    }
    if axes[2] >= phi {
        s |= 2;
    }
    if axes[4] < 0.0 {
        s |= 4;
    }
    let mut t = 0u8;
    for (i, a) in axes.iter().enumerate() {
        if *a < 0.0 {
            t |= 1 << i;
        }
    }
    (s, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_poses_of_model_md() {
        let r = RobotDescription::kr30ha();
        assert_eq!(status_turn(&r, &[0.0, -90.0, 90.0, 0.0, 0.0, 0.0]), (2, 2));
        assert_eq!(status_turn(&r, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), (0, 0));
        assert_eq!(
            status_turn(&r, &[30.0, -60.0, 100.0, 20.0, 40.0, -50.0]),
            (2, 34)
        );
        assert_eq!(
            status_turn(&r, &[-45.0, -112.0, 153.0, 0.0, -30.0, 90.0]),
            (6, 19)
        );
    }
}
