//! Rays, boxes and floating-point error bookkeeping shared by every path.

pub mod aabb;
pub mod float;
pub mod packet;
pub mod ray;
#[cfg(test)]
pub(crate) mod test_rng;

pub use aabb::Aabb;
pub use ray::Ray;
