//! Stages 2-3: seeding centers in the first frame and tracking them forward
//! (method.md §2-§5).

mod trajectories;

pub use trajectories::Trajectories;
