//! What the layer tells the user about its work, never on the app's output: the per-frame
//! statistics file (`stats_file`, `stats.file`), its per-second summary for `stereoshim stats`
//! and the overlay (`summary`), the never-silent notices of features that apply to nothing
//! (`notices`), what `stereoshim run` prints when the app exits (`run_summary`); `series` and
//! `plot` draw the stats file as a PNG (`stereoshim stats --plot`).

pub mod notices;
pub mod plot;
pub mod run_summary;
pub mod series;
pub mod stats_file;
pub mod summary;
