//! Calibration sessions laid out by another program: a **layout file** says which subfolders of
//! a session are the board poses (a pattern such as `capture_*`), which capture manifest
//! describes the frames of every pose folder, and which file of a pose folder is the board under
//! full white light (and under black). The user's files stay where and as they are: nothing is
//! renamed, linked or written into their folders.
//!
//! ```json
//! {
//!   "format": "sl-calibration-layout",
//!   "version": 1,
//!   "description": "kamino410/procam-calibration: OpenCV GrayCodePattern, 1024x768 projector",
//!   "poses": "capture_*",
//!   "manifest": "kamino-manifest.json",
//!   "white": "graycode_40.png",
//!   "black": "graycode_41.png"
//! }
//! ```
//!
//! `poses` is a glob pattern relative to the session folder (`*`, `?`, `[…]`, and `/` for
//! nested folders); the folders it matches, in name order, are the poses (files it matches are
//! ignored). `manifest` is an `sl-capture` manifest (`docs/capture-format.md`), relative to the
//! layout file; its frame names are looked for in each pose folder, and its projector size is
//! the projector's. `white` and `black` are file names inside each pose folder; without
//! `white` the board is found in the capture's own texture (`sl_codec::capture_texture`).
//! `turntable` (optional) is the folder of turntable views relative to the session, read as
//! `slscan calibrate turntable` reads one; without it `SESSION/turntable` is used when it
//! exists. Parsing is strict: an unknown key is an error naming it.
//!
//! An `slscan simulate` or `slscan calibrate capture` session needs no layout: each of its pose
//! folders holds its own `manifest.json` and `white.png` ([`PoseCapture::capture_folder`]).
//! Both kinds of session end as the same list of [`PoseCapture`]s, checked by
//! [`check_pose_files`] before anything is decoded and loaded by [`PoseCapture::load`].

use std::path::{Path, PathBuf};

use serde::Deserialize;
use sl_calib::{CalibError, ProcamView, load_grey};
use sl_camera::ImageSize;
use sl_codec::{
    CaptureSet, CodecError, DecodeConfig, Frame, MANIFEST_FILE, Manifest, capture_texture, decode,
    find_image_file,
};

/// Value of a layout file's `format` key.
pub const LAYOUT_FORMAT: &str = "sl-calibration-layout";

/// Version of the layout schema this crate reads.
pub const LAYOUT_VERSION: u64 = 1;

/// Fewest board poses a camera–projector calibration can use (Zhang's method needs three
/// views); fewer pose folders are refused before anything is decoded.
pub const MIN_POSES: usize = 3;

/// Everything that can be wrong with a calibration session's layout or files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LayoutError {
    /// A file or folder could not be read.
    #[error("{}: cannot read it: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The layout file is not valid JSON, has an unknown key, misses `poses` or `manifest`, or
    /// a value of the wrong type (the parser's message names the key, line and column).
    #[error("{}: {source}", path.display())]
    Json {
        /// The layout file.
        path: PathBuf,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A key of the layout file has a value out of its domain.
    #[error("{}: {key}: {message}", path.display())]
    Key {
        /// The layout file.
        path: PathBuf,
        /// The key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The layout's capture manifest cannot be read or is invalid, or a pose's frames cannot be
    /// read or decoded.
    #[error(transparent)]
    Codec(#[from] CodecError),
    /// A pose's white frame cannot be read.
    #[error(transparent)]
    Calib(#[from] CalibError),
    /// The `poses` pattern matches no folder of the session.
    #[error(
        "{}: poses: '{pattern}' matches no folder in {} ({files} file(s) matched): expected one \
         folder per board pose",
        layout.display(),
        session.display()
    )]
    NoPoses {
        /// The layout file.
        layout: PathBuf,
        /// The pattern as written.
        pattern: String,
        /// The session folder it was matched in.
        session: PathBuf,
        /// Files (not folders) it matched.
        files: usize,
    },
    /// A file a pose folder should hold is not there.
    #[error(
        "pose folder {}: no {what} '{file}' ({} does not exist, nor under another image extension)",
        pose.display(),
        path.display()
    )]
    MissingFile {
        /// The pose folder.
        pose: PathBuf,
        /// Which file: `frame 3 of block 0`, `white frame`, `black frame`.
        what: String,
        /// The file name as the manifest or the layout writes it.
        file: String,
        /// The path looked for.
        path: PathBuf,
    },
    /// A file a pose folder should hold names something that is not a regular file (a folder,
    /// a device, a FIFO: see `sl_codec::not_a_regular_file`).
    #[error("pose folder {}: {what} cannot be read: {} {why}", pose.display(), path.display())]
    NotAFile {
        /// The pose folder.
        pose: PathBuf,
        /// Which file: `frame 3 of block 0`, `white frame`, `black frame`.
        what: String,
        /// The path looked at (the file name as the manifest or the layout writes it, in the
        /// pose folder).
        path: PathBuf,
        /// What is there: `is a directory`, `is not a regular file (a character device)`, …
        why: String,
    },
    /// An image of the session has another size than the first one.
    #[error(
        "{}: {width}x{height} pixels, but {} has {first_width}x{first_height}: one camera, one \
         image size",
        file.display(),
        first.display()
    )]
    ImageSize {
        /// The image at fault.
        file: PathBuf,
        /// Its width (px).
        width: u32,
        /// Its height (px).
        height: u32,
        /// The first image of the session.
        first: PathBuf,
        /// The first image's width (px).
        first_width: u32,
        /// The first image's height (px).
        first_height: u32,
    },
    /// An image file's header cannot be read.
    #[error("{}: cannot read the image: {message}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Fewer pose folders than a calibration needs.
    #[error(
        "{found} board pose(s) in {}, at least {needed} needed (10–20 is better)",
        session.display()
    )]
    TooFewPoses {
        /// The session folder.
        session: PathBuf,
        /// Pose folders found.
        found: usize,
        /// Pose folders needed ([`MIN_POSES`]).
        needed: usize,
    },
    /// The projector size given differs from the one of the capture manifest, in whose pixels
    /// the decoded coordinates are.
    #[error(
        "the projector size {}x{} differs from the {}x{} of {}: the decoded projector \
         coordinates are in the manifest's pixels (leave the size out, or fix the manifest)",
        given.width,
        given.height,
        manifest_size.width,
        manifest_size.height,
        manifest.display()
    )]
    ProjectorSize {
        /// The manifest.
        manifest: PathBuf,
        /// The manifest's projector size.
        manifest_size: ImageSize,
        /// The size given.
        given: ImageSize,
    },
}

/// The layout file as written (strict: unknown keys are errors).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LayoutFile {
    format: Option<String>,
    version: Option<u64>,
    description: Option<String>,
    poses: String,
    manifest: PathBuf,
    white: Option<String>,
    black: Option<String>,
    turntable: Option<PathBuf>,
}

/// A calibration session's layout, read from a layout file ([`CalibrationLayout::load`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationLayout {
    /// The layout file (named in errors).
    pub source: PathBuf,
    /// Free text: where the session comes from.
    pub description: Option<String>,
    /// Glob pattern of the pose folders, relative to the session folder.
    pub poses: String,
    /// The capture manifest of every pose folder (resolved against the layout file's folder).
    pub manifest_path: PathBuf,
    /// The capture manifest, parsed and checked.
    pub manifest: Manifest,
    /// The white frame's file name inside each pose folder, if the capture has one.
    pub white: Option<String>,
    /// The black frame's file name inside each pose folder, if the capture has one.
    pub black: Option<String>,
    /// The folder of turntable views, relative to the session folder.
    pub turntable: Option<PathBuf>,
}

impl CalibrationLayout {
    /// Reads and checks a layout file, and the capture manifest it names.
    ///
    /// # Errors
    /// [`LayoutError::Io`], [`LayoutError::Json`] (syntax, unknown or missing key, wrong type),
    /// [`LayoutError::Key`] (a bad `format`, `version`, `poses`, `white`, `black`, or a manifest
    /// with its own `frames_dir`), [`LayoutError::Codec`] for the manifest.
    pub fn load(path: &Path) -> Result<Self, LayoutError> {
        let text = std::fs::read_to_string(path).map_err(|source| LayoutError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json_str(&text, path)
    }

    /// Parses layout text; `path` names the file in errors and is the folder the manifest's
    /// path is relative to.
    ///
    /// # Errors
    /// As [`CalibrationLayout::load`].
    pub fn from_json_str(text: &str, path: &Path) -> Result<Self, LayoutError> {
        let file: LayoutFile = serde_json::from_str(text).map_err(|source| LayoutError::Json {
            path: path.to_path_buf(),
            source,
        })?;
        let key = |key, message: String| LayoutError::Key {
            path: path.to_path_buf(),
            key,
            message,
        };
        if let Some(f) = &file.format
            && f != LAYOUT_FORMAT
        {
            return Err(key(
                "format",
                format!("must be \"{LAYOUT_FORMAT}\", got \"{f}\""),
            ));
        }
        if let Some(v) = file.version
            && v != LAYOUT_VERSION
        {
            return Err(key(
                "version",
                format!("this program reads version {LAYOUT_VERSION}, got {v}"),
            ));
        }
        if file.poses.trim().is_empty() || Path::new(&file.poses).is_absolute() {
            return Err(key(
                "poses",
                format!(
                    "'{}': expected a pattern relative to the session folder, such as \"capture_*\"",
                    file.poses
                ),
            ));
        }
        glob::Pattern::new(&file.poses)
            .map_err(|e| key("poses", format!("'{}': {e}", file.poses)))?;
        for (name, value) in [("white", &file.white), ("black", &file.black)] {
            if let Some(v) = value
                && (v.trim().is_empty() || Path::new(v).is_absolute())
            {
                return Err(key(
                    name,
                    format!("'{v}': expected a file name inside each pose folder"),
                ));
            }
        }
        let base = path.parent().unwrap_or(Path::new(""));
        let manifest_path = base.join(&file.manifest);
        let manifest = Manifest::load(&manifest_path)?;
        if let Some(d) = &manifest.frames_dir {
            return Err(key(
                "manifest",
                format!(
                    "{} sets frames_dir ({}): with a layout the frames are read in each pose \
                     folder; remove the key",
                    manifest_path.display(),
                    d.display()
                ),
            ));
        }
        Ok(Self {
            source: path.to_path_buf(),
            description: file.description,
            poses: file.poses,
            manifest_path,
            manifest,
            white: file.white,
            black: file.black,
            turntable: file.turntable,
        })
    }

    /// The pose folders of `session` in name order, each with its frames, white and black
    /// frame checked ([`check_pose_files`]).
    ///
    /// # Errors
    /// [`LayoutError::NoPoses`] when the pattern matches no folder, [`LayoutError::TooFewPoses`]
    /// with fewer than [`MIN_POSES`], and the errors of [`check_pose_files`].
    pub fn poses(&self, session: &Path) -> Result<Vec<PoseCapture>, LayoutError> {
        let folders = self.pose_folders(session)?;
        if folders.len() < MIN_POSES {
            return Err(LayoutError::TooFewPoses {
                session: session.to_path_buf(),
                found: folders.len(),
                needed: MIN_POSES,
            });
        }
        let poses: Vec<PoseCapture> = folders
            .into_iter()
            .map(|folder| {
                let name = folder
                    .strip_prefix(session)
                    .unwrap_or(&folder)
                    .to_string_lossy()
                    .into_owned();
                PoseCapture {
                    name,
                    manifest: self.manifest_path.clone(),
                    frames_dir: Some(folder.clone()),
                    white: self.white.as_ref().map(|w| folder.join(w)),
                    black: self.black.as_ref().map(|b| folder.join(b)),
                    folder,
                }
            })
            .collect();
        check_pose_files(&poses)?;
        Ok(poses)
    }

    /// The folders of `session` the `poses` pattern matches, in name order.
    fn pose_folders(&self, session: &Path) -> Result<Vec<PathBuf>, LayoutError> {
        if !session.is_dir() {
            return Err(LayoutError::Io {
                path: session.to_path_buf(),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no such folder (the session folder the layout describes)",
                ),
            });
        }
        let root = session.to_str().ok_or_else(|| LayoutError::Key {
            path: self.source.clone(),
            key: "poses",
            message: format!(
                "the session folder {} is not valid UTF-8: patterns cannot be matched in it",
                session.display()
            ),
        })?;
        let pattern = format!("{}/{}", glob::Pattern::escape(root), self.poses);
        let options = glob::MatchOptions {
            case_sensitive: true,
            require_literal_separator: true,
            require_literal_leading_dot: true,
        };
        let paths = glob::glob_with(&pattern, options).map_err(|e| LayoutError::Key {
            path: self.source.clone(),
            key: "poses",
            message: format!("'{}': {e}", self.poses),
        })?;
        let mut folders = Vec::new();
        let mut files = 0;
        for entry in paths {
            let path = entry.map_err(|e| LayoutError::Io {
                path: e.path().to_path_buf(),
                source: e.into(),
            })?;
            if path.is_dir() {
                folders.push(path);
            } else {
                files += 1;
            }
        }
        if folders.is_empty() {
            return Err(LayoutError::NoPoses {
                layout: self.source.clone(),
                pattern: self.poses.clone(),
                session: session.to_path_buf(),
                files,
            });
        }
        folders.sort();
        Ok(folders)
    }

    /// The folder of turntable views: the layout's `turntable`, else `SESSION/turntable` when
    /// it exists, else `None` (a camera and projector calibration only).
    ///
    /// # Errors
    /// [`LayoutError::Key`] when the layout names a folder that does not exist.
    pub fn turntable_dir(&self, session: &Path) -> Result<Option<PathBuf>, LayoutError> {
        match &self.turntable {
            Some(t) => {
                let dir = session.join(t);
                if dir.is_dir() {
                    Ok(Some(dir))
                } else {
                    Err(LayoutError::Key {
                        path: self.source.clone(),
                        key: "turntable",
                        message: format!("{}: no such folder", dir.display()),
                    })
                }
            }
            None => Ok(default_turntable_dir(session)),
        }
    }

    /// The projector size of the manifest.
    pub fn projector_size(&self) -> ImageSize {
        ImageSize::new(
            self.manifest.projector.width,
            self.manifest.projector.height,
        )
    }
}

/// `SESSION/turntable` when it is a folder.
pub fn default_turntable_dir(session: &Path) -> Option<PathBuf> {
    let dir = session.join(crate::TURNTABLE_DIR);
    dir.is_dir().then_some(dir)
}

/// One board pose of a calibration session: where its capture manifest, frames and white
/// frame are.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoseCapture {
    /// The view's name in messages, reports and picture names.
    pub name: String,
    /// The pose folder.
    pub folder: PathBuf,
    /// The capture manifest describing the pose's frames.
    pub manifest: PathBuf,
    /// Where the frames are, when not where the manifest says (a layout's pose folder).
    pub frames_dir: Option<PathBuf>,
    /// The board under full white light, if the capture has one.
    pub white: Option<PathBuf>,
    /// The board under black (the projector dark), if the capture has one: checked like the
    /// frames, not needed by the decoder (the Gray codes' inverses, or the fringes, are their
    /// own reference).
    pub black: Option<PathBuf>,
}

/// A decoded pose: the view `sl_calib::calibrate_procam` takes, and where its board picture
/// came from (`white.png`, `graycode_40.png`, or the capture texture's description).
#[derive(Debug, Clone)]
pub struct PoseView {
    /// The board picture and the decoded projector coordinates.
    pub view: ProcamView,
    /// The board picture's source, for the report.
    pub board_image: String,
    /// Whether the board picture is a white frame (not the capture's texture).
    pub white_frame: bool,
}

impl PoseCapture {
    /// A capture folder as `slscan simulate` and `slscan calibrate capture` write it: its own
    /// `manifest.json`, and `white.png` (under any image extension) if there is one.
    pub fn capture_folder(folder: &Path, name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            folder: folder.to_path_buf(),
            manifest: folder.join(MANIFEST_FILE),
            frames_dir: None,
            white: find_image_file(&folder.join(crate::WHITE_IMAGE)),
            black: None,
        }
    }

    /// Loads the frames, decodes them, and reads the board picture: the white frame, else the
    /// capture's own texture (the fringe mean of a phase block, the mean of a Gray block's
    /// patterns and inverses: `sl_codec::capture_texture`).
    ///
    /// # Errors
    /// [`LayoutError::Codec`] for the manifest, a frame or the decoding (naming the file),
    /// [`LayoutError::Calib`] for the white frame, [`LayoutError::ImageSize`] when the white
    /// frame's size differs from the frames'.
    pub fn load(&self, cfg: &DecodeConfig) -> Result<PoseView, LayoutError> {
        let set = CaptureSet::load_with_frames_dir(&self.manifest, self.frames_dir.as_deref())?;
        let map = decode(&set, cfg)?;
        let (lit, board_image, white_frame) = match &self.white {
            Some(white) => {
                let lit = load_grey(white)?;
                if (lit.width(), lit.height()) != (map.width, map.height) {
                    return Err(LayoutError::ImageSize {
                        file: white.clone(),
                        width: u32::try_from(lit.width()).unwrap_or(u32::MAX),
                        height: u32::try_from(lit.height()).unwrap_or(u32::MAX),
                        first: PathBuf::from(set.frame_names.first().cloned().unwrap_or_default()),
                        first_width: u32::try_from(map.width).unwrap_or(u32::MAX),
                        first_height: u32::try_from(map.height).unwrap_or(u32::MAX),
                    });
                }
                let name = white.file_name().map_or_else(
                    || white.display().to_string(),
                    |f| f.to_string_lossy().into_owned(),
                );
                (lit, name, true)
            }
            None => {
                let texture = capture_texture(&set)?;
                let (w, h) = (texture.width, texture.height);
                let bad = || LayoutError::Image {
                    path: self.folder.clone(),
                    message: format!("texture of {w}x{h} px"),
                };
                let lit = Frame::new(w, h, texture.to_u8()).map_err(|_| bad())?;
                (lit, texture.source.to_string(), false)
            }
        };
        Ok(PoseView {
            view: ProcamView {
                name: self.name.clone(),
                lit,
                map,
            },
            board_image,
            white_frame,
        })
    }

    /// The projector size of the pose's manifest.
    ///
    /// # Errors
    /// [`LayoutError::Codec`] when the manifest cannot be read.
    pub fn projector_size(&self) -> Result<ImageSize, LayoutError> {
        let m = Manifest::load(&self.manifest)?;
        Ok(ImageSize::new(m.projector.width, m.projector.height))
    }
}

/// The projector size a calibration of `poses` uses: `given` when it agrees with the first
/// pose's manifest, the manifest's when none is given.
///
/// # Errors
/// [`LayoutError::ProjectorSize`] when `given` differs from the manifest's;
/// [`LayoutError::TooFewPoses`] (found 0) for no poses; the manifest's errors.
pub fn projector_size(
    poses: &[PoseCapture],
    given: Option<ImageSize>,
) -> Result<ImageSize, LayoutError> {
    let Some(first) = poses.first() else {
        return Err(LayoutError::TooFewPoses {
            session: PathBuf::new(),
            found: 0,
            needed: MIN_POSES,
        });
    };
    let size = first.projector_size()?;
    match given {
        Some(g) if g != size => Err(LayoutError::ProjectorSize {
            manifest: first.manifest.clone(),
            manifest_size: size,
            given: g,
        }),
        _ => Ok(size),
    }
}

/// Checks, before anything is decoded, that every pose folder holds every frame its manifest
/// names, its white and black frame, and that all these images (read from their headers) have
/// the size of the first.
///
/// # Errors
/// [`LayoutError::MissingFile`] naming the pose folder and the file, [`LayoutError::NotAFile`]
/// when its path is a folder, a device or a FIFO, [`LayoutError::ImageSize`]
/// naming the image of another size, [`LayoutError::Image`] for an unreadable header,
/// [`LayoutError::Codec`] for a manifest.
pub fn check_pose_files(poses: &[PoseCapture]) -> Result<(), LayoutError> {
    let mut first: Option<(PathBuf, u32, u32)> = None;
    let mut manifests: Vec<(PathBuf, Manifest)> = Vec::new();
    for pose in poses {
        let manifest = match manifests.iter().find(|(p, _)| *p == pose.manifest) {
            Some((_, m)) => m.clone(),
            None => {
                let m = Manifest::load(&pose.manifest)?;
                manifests.push((pose.manifest.clone(), m.clone()));
                m
            }
        };
        let dir = match (&pose.frames_dir, &manifest.frames_dir) {
            (Some(d), _) => d.clone(),
            (None, frames_dir) => {
                let base = pose.manifest.parent().unwrap_or(Path::new(""));
                frames_dir
                    .as_ref()
                    .map_or_else(|| base.to_path_buf(), |d| base.join(d))
            }
        };
        let mut files: Vec<(String, String, PathBuf)> = Vec::new();
        for (b, block) in manifest.blocks.iter().enumerate() {
            for (i, file) in block.frames.iter().enumerate() {
                files.push((
                    format!("frame {i} of block {b}"),
                    file.clone(),
                    dir.join(file),
                ));
            }
        }
        for (what, path) in [("white frame", &pose.white), ("black frame", &pose.black)] {
            if let Some(p) = path {
                let file = p
                    .file_name()
                    .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
                files.push((what.to_owned(), file, p.clone()));
            }
        }
        for (what, file, path) in files {
            let Some(found) = find_image_file(&path) else {
                return Err(match sl_codec::not_a_regular_file(&path) {
                    Some(why) => LayoutError::NotAFile {
                        pose: pose.folder.clone(),
                        what,
                        path,
                        why,
                    },
                    None => LayoutError::MissingFile {
                        pose: pose.folder.clone(),
                        what,
                        file,
                        path,
                    },
                });
            };
            let (w, h) = image_size(&found)?;
            match &first {
                None => first = Some((found, w, h)),
                Some((f, fw, fh)) if (*fw, *fh) != (w, h) => {
                    return Err(LayoutError::ImageSize {
                        file: found,
                        width: w,
                        height: h,
                        first: f.clone(),
                        first_width: *fw,
                        first_height: *fh,
                    });
                }
                Some(_) => {}
            }
        }
    }
    Ok(())
}

/// An image file's size from its header (`sl_codec::read_image_size`).
fn image_size(path: &Path) -> Result<(u32, u32), LayoutError> {
    sl_codec::read_image_size(path).map_err(|e| LayoutError::Image {
        path: path.to_path_buf(),
        message: match e {
            sl_codec::CodecError::Image { source, .. } => source.to_string(),
            other => other.to_string(),
        },
    })
}

#[cfg(test)]
mod tests {
    //! The layout on small sessions written here: OpenCV-style per-pixel Gray codes of a 20x12
    //! projector, whose "capture" is the pattern images themselves (so every decoded pixel
    //! must be its own projector pixel), in pose folders without manifests.
    #![allow(clippy::unwrap_used, clippy::expect_used)]

    use std::path::{Path, PathBuf};

    use sl_codec::{
        Axis, BitDepth, DecodeConfig, Frame, GrayCodeSpec, ImageSize, MANIFEST_FILE, Pattern,
        PatternSequence, write_png_grey8,
    };

    use super::{CalibrationLayout, LayoutError, MIN_POSES, projector_size};

    const W: u32 = 20;
    const H: u32 = 12;

    /// A session of `poses` folders `capture_K` holding the pattern frames and `bright.png`,
    /// and `layout/` holding `manifest.json` and `layout.json` (poses `capture_*`, white
    /// `bright.png`). Returns (session, layout file).
    fn session(root: &Path, poses: usize) -> (PathBuf, PathBuf) {
        let p = ImageSize::new(W, H);
        let seq = PatternSequence::new(p)
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(
                Axis::Column,
                p,
                false,
            )))
            .with(Pattern::Gray(GrayCodeSpec::per_pixel(Axis::Row, p, false)));
        let session = root.join("session");
        for k in 0..poses {
            let dir = session.join(format!("capture_{k}"));
            seq.write(&dir, BitDepth::Eight).unwrap();
            std::fs::remove_file(dir.join(MANIFEST_FILE)).unwrap();
            let white = Frame::filled(W as usize, H as usize, 255).unwrap();
            write_png_grey8(&dir.join("bright.png"), &white).unwrap();
        }
        let layout_dir = root.join("layout");
        std::fs::create_dir_all(&layout_dir).unwrap();
        seq.manifest(BitDepth::Eight)
            .save(&layout_dir.join("manifest.json"))
            .unwrap();
        let layout = layout_dir.join("layout.json");
        std::fs::write(
            &layout,
            r#"{"format": "sl-calibration-layout", "version": 1, "poses": "capture_*",
                "manifest": "manifest.json", "white": "bright.png"}"#,
        )
        .unwrap();
        (session, layout)
    }

    #[test]
    fn poses_are_the_matching_folders_in_name_order_and_decode_in_place() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        // A file that matches the pattern and a folder that does not are not poses.
        std::fs::write(session.join("capture_notes.txt"), "x").unwrap();
        std::fs::create_dir_all(session.join("other")).unwrap();
        let l = CalibrationLayout::load(&layout).unwrap();
        let poses = l.poses(&session).unwrap();
        let names: Vec<&str> = poses.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["capture_0", "capture_1", "capture_2"]);
        assert_eq!(
            poses[1].white.as_deref(),
            Some(session.join("capture_1/bright.png").as_path())
        );
        assert_eq!(l.projector_size(), sl_camera::ImageSize::new(W, H));
        let v = poses[2].load(&DecodeConfig::default()).unwrap();
        assert!(v.white_frame);
        assert_eq!(v.board_image, "bright.png");
        assert_eq!(v.view.name, "capture_2");
        // The frames are the patterns: every pixel decodes to itself (OpenCV's convention).
        let map = &v.view.map;
        for y in 0..H as usize {
            for x in 0..W as usize {
                let i = y * map.width + x;
                assert_eq!((map.col[i], map.row[i]), (x as f32, y as f32), "({x}, {y})");
            }
        }
        // No layout needed beside the frames: nothing was written into the session.
        assert!(!session.join("capture_0").join(MANIFEST_FILE).exists());
    }

    #[test]
    fn a_pattern_matching_no_folder_is_an_error_naming_it() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        std::fs::write(session.join("shot_1.png"), "x").unwrap();
        let text = std::fs::read_to_string(&layout)
            .unwrap()
            .replace("capture_*", "shot_*");
        let l = CalibrationLayout::from_json_str(&text, &layout).unwrap();
        let err = l.poses(&session).unwrap_err();
        assert!(
            matches!(&err, LayoutError::NoPoses { pattern, files: 1, .. } if pattern == "shot_*"),
            "{err:?}"
        );
        assert!(
            err.to_string().contains("'shot_*' matches no folder"),
            "{err}"
        );
    }

    #[test]
    fn a_frame_missing_in_one_pose_folder_names_the_folder_and_the_file() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        std::fs::remove_file(session.join("capture_1/003.png")).unwrap();
        let err = CalibrationLayout::load(&layout)
            .unwrap()
            .poses(&session)
            .unwrap_err();
        match &err {
            LayoutError::MissingFile {
                pose, file, what, ..
            } => {
                assert_eq!(pose, &session.join("capture_1"));
                assert_eq!(file, "003.png");
                assert_eq!(what, "frame 3 of block 0");
            }
            other => panic!("{other:?}"),
        }
        let text = err.to_string();
        assert!(
            text.contains("capture_1") && text.contains("003.png"),
            "{text}"
        );
    }

    #[test]
    fn a_missing_white_frame_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        std::fs::remove_file(session.join("capture_2/bright.png")).unwrap();
        let err = CalibrationLayout::load(&layout)
            .unwrap()
            .poses(&session)
            .unwrap_err();
        assert!(
            matches!(&err, LayoutError::MissingFile { what, file, .. } if what == "white frame" && file == "bright.png"),
            "{err:?}"
        );
    }

    #[test]
    fn an_image_of_another_size_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        let odd = session.join("capture_2/bright.png");
        let wide = Frame::filled(W as usize + 1, H as usize, 255).unwrap();
        write_png_grey8(&odd, &wide).unwrap();
        let err = CalibrationLayout::load(&layout)
            .unwrap()
            .poses(&session)
            .unwrap_err();
        match &err {
            LayoutError::ImageSize {
                file,
                width,
                first_width,
                ..
            } => {
                assert_eq!(file, &odd);
                assert_eq!((*width, *first_width), (W + 1, W));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn fewer_pose_folders_than_a_calibration_needs_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), MIN_POSES - 1);
        let err = CalibrationLayout::load(&layout)
            .unwrap()
            .poses(&session)
            .unwrap_err();
        assert!(
            matches!(
                err,
                LayoutError::TooFewPoses {
                    found: 2,
                    needed: 3,
                    ..
                }
            ),
            "{err:?}"
        );
    }

    #[test]
    fn keys_are_checked_and_named() {
        let tmp = tempfile::tempdir().unwrap();
        let (_, layout) = session(tmp.path(), 3);
        let parse = |text: &str| CalibrationLayout::from_json_str(text, &layout).unwrap_err();
        let base = r#""poses": "capture_*", "manifest": "manifest.json""#;
        // A misspelt key, a missing key: serde's message names them.
        let e = parse(r#"{"pose": "capture_*", "manifest": "manifest.json"}"#);
        assert!(e.to_string().contains("unknown field `pose`"), "{e}");
        let e = parse(r#"{"poses": "capture_*"}"#);
        assert!(e.to_string().contains("missing field `manifest`"), "{e}");
        let key = |text: &str| match parse(text) {
            LayoutError::Key { key, .. } => key,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            key(&format!(r#"{{"format": "sl-capture", {base}}}"#)),
            "format"
        );
        assert_eq!(key(&format!(r#"{{"version": 2, {base}}}"#)), "version");
        assert_eq!(
            key(r#"{"poses": "capture_[", "manifest": "manifest.json"}"#),
            "poses"
        );
        assert_eq!(
            key(r#"{"poses": "/abs/capture_*", "manifest": "manifest.json"}"#),
            "poses"
        );
        assert_eq!(key(&format!(r#"{{"white": "", {base}}}"#)), "white");
        // A manifest that says where its frames are contradicts the layout.
        let dir = layout.parent().unwrap();
        let mut m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap())
                .unwrap();
        m["frames_dir"] = serde_json::json!("frames");
        std::fs::write(dir.join("manifest.json"), m.to_string()).unwrap();
        assert_eq!(key(&format!("{{{base}}}")), "manifest");
        // A manifest that is not there: the codec's error, naming the file.
        let e = parse(r#"{"poses": "capture_*", "manifest": "nowhere.json"}"#);
        assert!(
            matches!(&e, LayoutError::Codec(_)) && e.to_string().contains("nowhere.json"),
            "{e}"
        );
    }

    #[test]
    fn the_projector_size_is_the_manifests_and_another_one_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let (session, layout) = session(tmp.path(), 3);
        let poses = CalibrationLayout::load(&layout)
            .unwrap()
            .poses(&session)
            .unwrap();
        let size = sl_camera::ImageSize::new(W, H);
        assert_eq!(projector_size(&poses, None).unwrap(), size);
        assert_eq!(projector_size(&poses, Some(size)).unwrap(), size);
        let err = projector_size(&poses, Some(sl_camera::ImageSize::new(1920, 1080))).unwrap_err();
        assert!(
            matches!(err, LayoutError::ProjectorSize { given, manifest_size, .. }
                if given.width == 1920 && manifest_size == size),
            "{err:?}"
        );
    }
}
