//! Fuzz the PLY reader: any byte string must give `Ok` or `Err`, never a panic, an abort or an
//! absurd allocation.
//!
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run ply_read -- -max_total_time=60` from `fuzz/`; seed the
//! corpus with `mkdir -p corpus/ply_read && cp ../crates/sl-cloud/tests/data/*.ply corpus/ply_read/`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(cloud) = sl_cloud::read_ply_from_bytes(data) {
        // Whatever was read must be internally consistent and re-writable.
        let n = cloud.len();
        assert!(cloud.normals().is_none_or(|v| v.len() == n));
        assert!(cloud.colors().is_none_or(|v| v.len() == n));
        assert!(cloud.quality().is_none_or(|v| v.len() == n));
        let bytes = sl_cloud::write_ply_to_bytes(&cloud, sl_cloud::PlyFormat::default());
        let back = sl_cloud::read_ply_from_bytes(&bytes);
        assert!(back.is_ok_and(|b| b.len() == n));
    }
});
