//! Structured-light pattern sequences and their decoders.
//!
//! **Status: placeholder.** This crate exists so that the workspace has its final shape; it
//! contains no code yet, and nothing in it pretends to work.
//!
//! It will hold the pattern generators and decoders of the scanner: Gray code (with inverse or
//! white/black reference frames, plain binary as an option), N-step phase shift, temporal phase
//! unwrapping (multi-frequency hierarchical, three-frequency heterodyne, number-theoretic) and the
//! hybrid Gray code + phase shift with a complementary Gray pattern. Camera images go in; a
//! correspondence map comes out: for every camera pixel, the projector column and row that lit
//! it, a quality value and the reason a pixel is invalid. Capture sets are read from a folder of
//! frames plus a `manifest.json`.
//!
//! Tracked by issue 3.
#![deny(missing_docs)]
