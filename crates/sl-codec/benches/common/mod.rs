//! The benchmark scene shared by the decode benches: a 1280x720 camera looking at a 1920x1080
//! projector (1.4 projector pixels per camera pixel), with noise, ambient light and albedo
//! variation, rendered once outside the timing.

use sl_codec::{Frame, ImageSize, PatternSequence, SyntheticScene};

pub(crate) const PROJECTOR: ImageSize = ImageSize {
    width: 1920,
    height: 1080,
};

pub(crate) fn scene() -> SyntheticScene {
    SyntheticScene {
        noise_sigma: 2.0,
        ambient: 10.0,
        albedo_min: 0.5,
        blur: 0.5,
        ..SyntheticScene::window(PROJECTOR, 1280, 720, 1.4)
    }
}

pub(crate) fn render(sequence: &PatternSequence) -> Vec<Frame<u8>> {
    match scene().render(sequence) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("rendering the benchmark frames failed: {e}");
            std::process::exit(1)
        }
    }
}
