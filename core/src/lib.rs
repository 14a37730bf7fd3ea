//! HORT-serverless core: a pure ray tracing library and the HORT MapReduce stages as pure
//! functions over bytes. No AWS, no async runtime, no platform libm in anything that reaches an
//! output: the same inputs give the same bytes on every machine.
// Unsafe code is refused except where a module allows it and says why: the AVX lanes of the
// ray kernels (`bvh/lanes.rs`) and the calls that enter them after detecting AVX2.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod error;
mod error_type;
pub mod plural;
pub use error_type::ErrorType;

// Scene input and the renderer.
pub mod adaptive;
pub mod animation;
pub mod bvh;
pub mod camera;
pub mod coverage;
mod morton;
pub mod phase_timer;
mod prefetch;
pub mod render;
pub mod sampling;
pub mod scene;
#[cfg(test)]
mod scratch;
pub mod shading;
pub mod terminator;
pub mod texture;
pub mod tiles;
pub mod triangle;
pub mod unoccludable;

// Outputs.
pub mod breakdown;
pub mod cost;
pub mod hits;
pub mod image;
pub mod report;

// Synthetic scenes for benchmarks.
pub mod generate;

// HORT pipeline building blocks.
pub mod digest;
pub mod ids;
pub mod keys;
pub mod pipeline;
pub mod predict;
pub mod shuffle;
pub mod stage;
pub mod store;
pub mod task_metrics;

// Shared machinery.
pub mod worker_pool;
