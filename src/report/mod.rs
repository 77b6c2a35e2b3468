//! What the layer tells the user about its work, never on the app's output: the per-frame
//! statistics file (`stats_file`, `stats.file`), its per-second summary for `stereoshim stats`
//! and the overlay (`summary`), and the never-silent notices of features that apply to nothing
//! (`notices`); `series` and `plot` draw the stats file as a PNG (`stereoshim stats --plot`).

pub mod notices;
pub mod plot;
pub mod series;
pub mod stats_file;
pub mod summary;
