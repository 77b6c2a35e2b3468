//! Variable-rate shading (foveation method 1): `rules` is the pure rate map; `vk` keeps the
//! layer's rate images and chains them into eye passes; `pass` amends the app's render passes,
//! framebuffers and pipelines so a rate attachment can be chained at all; `submission` fills the
//! maps of passes whose eyes only each submission's walk gives.

pub(crate) mod pass;
pub mod rules;
mod submission;
pub(crate) mod vk;
