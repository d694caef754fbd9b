//! Data association: for one source point (already moved into the target frame), the index of
//! its target point and their squared distance. Every function here is allocation-free.

pub(crate) mod closest;
pub(crate) mod normal_shooting;
pub(crate) mod projective;
