//! The geometric stability suite: the scenes of `scenes/stability/` (and larger ones generated
//! here) rendered where floating point is at its weakest. Each module is one case of the table
//! in `scenes/stability/README.md`; each test prints the figure that table records
//! (`cargo test -p hort-core --test stability -- --nocapture`).

mod closed_meshes;
mod coplanar;
mod degenerate;
mod grazing;
mod splits;
mod support;
mod transformed;
