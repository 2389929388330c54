//! Temporary: the accessor the coming `AxisHistory` provides (BRIEF "Coming change"); dropped at
//! the merge with issue 22.

impl super::AxisState {
    /// The rotation direction of every axis (the old view of the axis histories).
    pub fn directions(&self) -> [super::Direction; 6] {
        self.directions
    }
}
