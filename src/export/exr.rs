//! OpenEXR output: center trajectories and vertex-animation textures.
