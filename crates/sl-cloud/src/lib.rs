//! Point clouds (in progress).
#![deny(missing_docs)]
