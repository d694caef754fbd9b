//! `slscan`: the structured-light scanner's command line.
fn main() {}
