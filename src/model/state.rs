//! What the error model is evaluated at: the command axis angles, each axis's rotation
//! direction (which backlash branch it sits on) and the time since the start of the campaign.

/// The rotation direction of one axis at a stop: the sign of its last motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Direction {
    Negative,
    /// The axis has not moved yet: models use the mean of both branches.
    #[default]
    Unknown,
    Positive,
}

impl Direction {
    /// +1, −1, or 0 for unknown.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Negative => -1.0,
            Direction::Unknown => 0.0,
            Direction::Positive => 1.0,
        }
    }

    /// The direction of a move by `delta` degrees, keeping `self` when the axis does not move.
    pub fn after_move(self, delta: f64) -> Direction {
        if delta > 0.0 {
            Direction::Positive
        } else if delta < 0.0 {
            Direction::Negative
        } else {
            self
        }
    }

    pub fn from_sign(s: i32) -> Direction {
        match s.signum() {
            1 => Direction::Positive,
            -1 => Direction::Negative,
            _ => Direction::Unknown,
        }
    }
}

/// The state at which the error model is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisState {
    /// Command angles A1..A6 in degrees (KUKA convention, as on the teach pendant).
    pub axes_deg: [f64; 6],
    /// Rotation direction of each axis at this stop.
    pub directions: [Direction; 6],
    /// Seconds since the start of the campaign (the `drift` effect's clock).
    pub time_s: f64,
}

impl AxisState {
    pub fn new(axes_deg: [f64; 6]) -> Self {
        AxisState {
            axes_deg,
            directions: [Direction::Unknown; 6],
            time_s: 0.0,
        }
    }
}
