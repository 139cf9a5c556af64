//! Reading center trajectories back from OpenEXR.
