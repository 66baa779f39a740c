//! Rays and floating-point error bookkeeping shared by every path.

pub mod float;
pub mod packet;
pub mod ray;

pub use ray::Ray;
