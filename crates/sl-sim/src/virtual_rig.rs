//! The virtual rig: casts each view once, renders frames as lookups, and exposes itself
//! through the device traits.

use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

use nalgebra::Point3;

use sl_image::Frame;

use crate::geometry::{CameraRays, Caster};
use crate::render::Weights;
use crate::sensor::{BitDepth, NoiseKey, expose};
use crate::truth::{ObjectPose, TrueColour};
use crate::{
    Camera, ColourImage, GreyImage, Mount, PlacedScene, Projector, ProjectorSampling, RenderConfig,
    RigConfig, RigError, Scene, SimError, Turntable, ViewGeometry, ViewTruth,
};

/// A virtual structured-light rig looking at a scene.
///
/// Use it directly ([`VirtualRig::view`] casts a view, [`View::capture`] renders frames), or
/// through the device traits with [`VirtualRig::devices`], exactly like real hardware.
#[derive(Debug, Clone)]
pub struct VirtualRig {
    config: Arc<RigConfig>,
    scene: Arc<Scene>,
    rays: Arc<OnceLock<CameraRays>>,
}

/// One view of the scene (one turntable position): the geometry cache, the ground truth, and
/// what is needed to render frames.
#[derive(Debug, Clone)]
pub struct View {
    /// Per-sub-sample geometry: every projected image renders from it.
    pub geometry: ViewGeometry,
    /// Ground truth at pixel centres.
    pub truth: ViewTruth,
    /// Index of the view (keys the noise).
    pub index: u64,
    render: RenderConfig,
    fx: f64,
}

impl VirtualRig {
    /// A rig looking at `scene`; fails when the configuration or the scene is invalid.
    pub fn new(config: RigConfig, scene: Scene) -> Result<Self, SimError> {
        config.validate()?;
        scene.validate()?;
        Ok(Self {
            config: Arc::new(config),
            scene: Arc::new(scene),
            rays: Arc::new(OnceLock::new()),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RigConfig {
        &self.config
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The same rig (sharing its camera-ray cache) looking at another scene.
    pub fn with_scene(&self, scene: Scene) -> Result<Self, SimError> {
        scene.validate()?;
        Ok(Self {
            config: self.config.clone(),
            scene: Arc::new(scene),
            rays: self.rays.clone(),
        })
    }

    /// The camera's rays (computed on first use, then shared by every view and every clone).
    pub fn camera_rays(&self) -> &CameraRays {
        self.rays
            .get_or_init(|| CameraRays::new(&self.config.camera, self.config.render.supersampling))
    }

    /// Casts the view with the turntable motor at `motor_angle_deg`: the geometry cache (with
    /// the configured super-sampling) and the ground truth. `index` keys the view's noise.
    pub fn view(&self, motor_angle_deg: f64, index: u64) -> Result<View, SimError> {
        if !motor_angle_deg.is_finite() {
            return Err(SimError::param(
                "turntable angle",
                format!("{motor_angle_deg} is not finite"),
            ));
        }
        let t_cam_table = self.config.t_cam_table_at(motor_angle_deg);
        let placed = PlacedScene::new(&self.scene, &t_cam_table);
        let caster = Caster {
            scene: &placed,
            rays: self.camera_rays(),
            projector: &self.config.projector,
            t_cam_proj: &self.config.t_cam_proj,
        };
        let mut truth = caster.truth_maps();
        let mut geometry = caster.geometry();
        geometry.depth_mm = truth.depth_mm.iter().map(|&d| d as f32).collect();
        truth.motor_angle_deg = motor_angle_deg;
        truth.platter_angle_deg = self.config.platter_angle_deg(motor_angle_deg);
        truth.t_cam_table = t_cam_table;
        truth.objects = self
            .scene
            .objects
            .iter()
            .map(|o| ObjectPose {
                name: o.name.clone(),
                t_cam_object: match o.mount {
                    Mount::Turntable => t_cam_table * o.pose,
                    Mount::Camera => o.pose,
                },
            })
            .collect();
        Ok(View {
            geometry,
            truth,
            index,
            render: self.config.render,
            fx: self.config.camera.intrinsics.fx,
        })
    }

    /// The true colour of the scene's surface nearest `p_cam`, a point in the camera frame of
    /// the view with the turntable motor at `motor_deg` (objects on the turntable are at
    /// `t_cam_table_at(motor_deg) · pose`, objects fixed to the camera at their pose): the
    /// RGB albedo of the texture at the nearest surface point and the distance to it. Judges
    /// a scan's colours: a reconstructed point with its colour is compared with the albedo
    /// of the surface it lies on (a fraction of a millimetre away).
    ///
    /// `None` when `p_cam` or `motor_deg` is not finite, or when the nearest point is not
    /// defined (`p_cam` at a sphere's centre).
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_sim::{Finish, RigConfig, Scene, VirtualRig};
    /// # fn main() -> Result<(), sl_sim::SimError> {
    /// let rig = VirtualRig::new(RigConfig::default(), Scene::sphere().finished(Finish::Dark))?;
    /// // The sphere (radius 50 mm) stands on the table's axis, its centre 50 mm up: a point
    /// // 80 mm from the axis on the camera's side (table y < 0) is 30 mm from its surface.
    /// let p = rig.config().t_cam_table_at(0.0) * Point3::new(0.0, -80.0, 50.0);
    /// let truth = rig.true_colour(0.0, &p).unwrap();
    /// assert!((truth.distance_mm - 30.0).abs() < 1e-6);
    /// assert_eq!(truth.rgb, [sl_sim::DARK_ALBEDO; 3]);
    /// # Ok(()) }
    /// ```
    pub fn true_colour(&self, motor_deg: f64, p_cam: &Point3<f64>) -> Option<TrueColour> {
        if !(motor_deg.is_finite() && p_cam.coords.iter().all(|c| c.is_finite())) {
            return None;
        }
        let placed = PlacedScene::new(&self.scene, &self.config.t_cam_table_at(motor_deg));
        let (k, local, distance_mm) = placed.nearest_surface(p_cam)?;
        let object = self.scene.objects.get(k)?;
        Some(TrueColour {
            rgb: object.texture.albedo_rgb_at(&local),
            distance_mm,
            object: object.name.clone(),
        })
    }

    /// How a capture session names this rig's devices: `virtual camera WxH`, `virtual
    /// projector WxH` and the given `turntable`.
    #[must_use]
    pub fn session_devices(&self, turntable: &str) -> sl_rig::SessionDevices {
        let (c, p) = (self.config().camera.size, self.config().projector.size);
        sl_rig::SessionDevices {
            camera: format!("virtual camera {}x{}", c.width, c.height),
            projector: format!("virtual projector {}x{}", p.width, p.height),
            turntable: turntable.to_owned(),
            right_camera: None,
        }
    }

    /// The rig as three devices sharing one state: showing an image on the projector changes
    /// what the camera captures, turning the table changes the view.
    pub fn devices(&self) -> (VirtualCamera, VirtualProjector, VirtualTurntable) {
        let state = Arc::new(Mutex::new(DeviceState::default()));
        (
            self.camera_on(&state),
            VirtualProjector {
                state: state.clone(),
                size: (
                    self.config.projector.size.width,
                    self.config.projector.size.height,
                ),
            },
            VirtualTurntable { state },
        )
    }

    /// The rig with a second camera (binocular structured light): `right` is the same scene
    /// seen from the second camera ([`RigConfig::seen_from`]). The four devices share one
    /// state: both cameras see what the one projector shows on the one turntable.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] when the two rigs differ in their projector's size.
    pub fn binocular_devices(
        &self,
        right: &VirtualRig,
    ) -> Result<
        (
            VirtualCamera,
            VirtualCamera,
            VirtualProjector,
            VirtualTurntable,
        ),
        SimError,
    > {
        if right.config.projector.size != self.config.projector.size {
            return Err(SimError::param(
                "second camera's rig",
                format!(
                    "its projector is {} but the first camera's is {}: one projector lights both",
                    right.config.projector.size, self.config.projector.size
                ),
            ));
        }
        let (left, projector, turntable) = self.devices();
        let right = right.camera_on(&left.state);
        Ok((left, right, projector, turntable))
    }

    /// This rig's camera on the shared device `state`.
    fn camera_on(&self, state: &Arc<Mutex<DeviceState>>) -> VirtualCamera {
        VirtualCamera {
            rig: self.clone(),
            state: state.clone(),
            cache: Arc::new(Mutex::new(ViewCache::default())),
            exposure_ms: VIRTUAL_EXPOSURE_MS,
        }
    }
}

impl View {
    /// Renders the frame the camera captures while the projector shows `image`; `frame`
    /// keys the noise (the same frame index gives the same noise).
    pub fn capture(&self, image: &GreyImage, frame: u64) -> Result<GreyImage, SimError> {
        self.capture_exposed(image, frame, 1.0)
    }

    /// [`View::capture`] with the sensor's exposure multiplied by `exposure_scale`: the
    /// frame a camera captures with a longer (`> 1`) or shorter exposure time, photon noise
    /// and saturation included.
    pub fn capture_exposed(
        &self,
        image: &GreyImage,
        frame: u64,
        exposure_scale: f64,
    ) -> Result<GreyImage, SimError> {
        let radiance = self
            .geometry
            .render_image(image, &self.render.illumination)?;
        self.expose_scaled(radiance, frame, exposure_scale)
    }

    /// Renders the frame a colour camera captures while the projector shows `projected`; `frame`
    /// keys the noise, as in [`View::capture`].
    ///
    /// The projector's light is white: each channel is rendered with that channel's albedo
    /// ([`Texture::albedo_rgb_at`](crate::Texture::albedo_rgb_at), the grey albedo in every
    /// channel for grey textures) through the same optics and sensor as a grey frame (lens and
    /// projector blur, global illumination, defocus, exposure, saturation), its photon and
    /// read noise drawn independently of the other channels' and of the grey frames', and
    /// quantised to 8 bits whatever the sensor's bit depth. Since the grey albedo of a colour
    /// texture is its luma, the luma of a colour frame ([`ColourImage::to_grey`]) is the grey
    /// frame of an 8-bit sensor, within the noise.
    ///
    /// # Errors
    /// [`SimError::Rig`] when `projected` does not have the projector's size.
    pub fn capture_colour(
        &self,
        projected: &GreyImage,
        frame: u64,
    ) -> Result<ColourImage, SimError> {
        self.capture_colour_exposed(projected, frame, 1.0)
    }

    /// [`View::capture_colour`] with the sensor's exposure multiplied by `exposure_scale`, as
    /// [`View::capture_exposed`].
    ///
    /// # Errors
    /// As [`View::capture_colour`].
    pub fn capture_colour_exposed(
        &self,
        projected: &GreyImage,
        frame: u64,
        exposure_scale: f64,
    ) -> Result<ColourImage, SimError> {
        let g = &self.geometry;
        let light = &self.render.illumination;
        let radiances = if g.colour.is_empty() {
            // A grey scene: the three channels see the grey albedo.
            let r = g.render_image(projected, light)?;
            vec![r.clone(), r.clone(), r]
        } else {
            let channel = |c: usize| -> (Vec<f32>, Vec<f32>) {
                g.colour
                    .iter()
                    .zip(g.lit_weight.iter().zip(&g.ambient_weight))
                    .map(|(rgb, (&lit, &amb))| {
                        let a = rgb.get(c).copied().unwrap_or(0.0);
                        (lit + (a - amb) * rgb[3], a)
                    })
                    .unzip()
            };
            let weights: Vec<(Vec<f32>, Vec<f32>)> = (0..3).map(channel).collect();
            let weights: Vec<Weights<'_>> = weights
                .iter()
                .map(|(lit, ambient)| Weights { lit, ambient })
                .collect();
            g.render_image_weighted(projected, light, &weights)?
        };
        let mut effects = self.render.effects;
        effects.sensor.exposure *= exposure_scale;
        effects.sensor.bit_depth = BitDepth::Eight;
        let (w, h) = (g.width as usize, g.height as usize);
        let mut data = vec![[0u8; 3]; w * h];
        for (c, (radiance, salt)) in radiances.into_iter().zip(COLOUR_NOISE_SALTS).enumerate() {
            let key = NoiseKey {
                seed: self.render.seed ^ salt,
                view: self.index,
                frame,
            };
            let channel = expose(radiance, w, h, &g.depth_mm, self.fx, &effects, key)?.into_u8();
            for (o, &v) in data.iter_mut().zip(channel.data()) {
                if let Some(slot) = o.get_mut(c) {
                    *slot = v;
                }
            }
        }
        Ok(ColourImage::new(w, h, data)?)
    }

    /// Renders the frame the camera captures while the projector shows the pattern `pattern`
    /// (a function of the projector coordinate returning a value in `[0, 1]`).
    ///
    /// # Errors
    /// [`SimError::Image`] if the camera has no pixels.
    pub fn capture_fn<F>(
        &self,
        pattern: F,
        sampling: ProjectorSampling,
        frame: u64,
    ) -> Result<GreyImage, SimError>
    where
        F: Fn(f64, f64) -> f64 + Sync,
    {
        let radiance = self
            .geometry
            .render_fn(pattern, sampling, &self.render.illumination);
        self.expose(radiance, frame)
    }

    /// Renders one frame per projector image, frame `k` under `images[k]`.
    pub fn capture_all(&self, images: &[GreyImage]) -> Result<Vec<GreyImage>, SimError> {
        images
            .iter()
            .enumerate()
            .map(|(k, img)| {
                self.capture(img, k as u64).map_err(|e| match e {
                    SimError::Rig(RigError::ImageSize {
                        expected_width,
                        expected_height,
                        width,
                        height,
                        ..
                    }) => SimError::Rig(RigError::ImageSize {
                        what: format!("projector image {k}"),
                        expected_width,
                        expected_height,
                        width,
                        height,
                    }),
                    other => other,
                })
            })
            .collect()
    }

    fn expose(&self, radiance: Vec<f32>, frame: u64) -> Result<GreyImage, SimError> {
        self.expose_scaled(radiance, frame, 1.0)
    }

    fn expose_scaled(
        &self,
        radiance: Vec<f32>,
        frame: u64,
        exposure_scale: f64,
    ) -> Result<GreyImage, SimError> {
        let mut effects = self.render.effects;
        effects.sensor.exposure *= exposure_scale;
        let key = NoiseKey {
            seed: self.render.seed,
            view: self.index,
            frame,
        };
        expose(
            radiance,
            self.geometry.width as usize,
            self.geometry.height as usize,
            &self.geometry.depth_mm,
            self.fx,
            &effects,
            key,
        )
    }
}

/// Mixed into the rig's seed for the noise of a colour frame's red, green and blue channels:
/// three streams unrelated to each other and to the grey frames' (the noise key's mix has full
/// avalanche, so any three distinct non-zero constants do; these are the first 64 bits of the
/// fractional parts of √2, √3 and √5).
const COLOUR_NOISE_SALTS: [u64; 3] = [
    0x6A09_E667_F3BC_C908,
    0xBB67_AE85_84CA_A73B,
    0x3C6E_F372_FE94_F82B,
];

/// Frames that lie, on demand: the virtual devices told to be late, caught mid-update or to
/// deliver a stale frame, as real projectors and cameras are ([`VirtualProjector::set_faults`]).
/// Shows and captures are counted from 0 over the devices' life, so that a capture session's
/// frame `k` of view `v` is show `v · frames + k` when nothing is captured again.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DeviceFaults {
    /// Shows the projector is late with: until `late_by` has passed since [`Projector::show`],
    /// a camera sees the previous image.
    pub late_shows: Vec<u64>,
    /// Shows a camera catches half-updated: until `late_by` has passed, the top half of its
    /// rows still shows the previous image.
    pub mixed_shows: Vec<u64>,
    /// How long a late or mixed show takes to settle.
    pub late_by: std::time::Duration,
    /// Captures (of each camera, counted from 0) at which the camera delivers its previous
    /// frame again: a dropped frame.
    pub stale_captures: Vec<u64>,
}

/// How the projector's current image is still settling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Settling {
    Late,
    Mixed,
}

/// What the devices share: the platter's angle and the projector's image.
#[derive(Debug, Default)]
struct DeviceState {
    motor_angle_deg: f64,
    /// Counts the turntable's moves: a camera whose view is of another move casts again.
    moves: u64,
    shown: Option<GreyImage>,
    /// The image shown before `shown`, and how `shown` is still settling (since when).
    previous: Option<GreyImage>,
    settling: Option<(Settling, std::time::Instant)>,
    shows: u64,
    faults: DeviceFaults,
}

impl DeviceState {
    /// How the projector's image is still settling now.
    fn settling(&self) -> Option<Settling> {
        self.settling
            .filter(|(_, since)| since.elapsed() < self.faults.late_by)
            .map(|(how, _)| how)
    }
}

/// A camera's view of the current platter position, cast on first use.
#[derive(Debug, Default)]
struct ViewCache {
    view: Option<(u64, Arc<View>)>,
    views_cast: u64,
    frames_in_view: u64,
    /// Captures so far, and the last frame delivered (for [`DeviceFaults::stale_captures`]).
    captures: u64,
    last: Option<GreyImage>,
}

fn lock<T>(state: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic in another thread while holding the lock leaves a state that is still
    // consistent (every field is replaced whole), so a poisoned lock is safe to reuse.
    state
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The virtual rig's camera ([`Camera`]).
#[derive(Debug, Clone)]
pub struct VirtualCamera {
    rig: VirtualRig,
    state: Arc<Mutex<DeviceState>>,
    cache: Arc<Mutex<ViewCache>>,
    /// The exposure time ([`Camera::set_exposure_ms`]); the sensor's
    /// [`exposure`](crate::SensorConfig::exposure) is that of [`VIRTUAL_EXPOSURE_MS`].
    exposure_ms: f64,
}

/// The exposure time of the virtual camera's frames as the rig's sensor describes them
/// ([`SensorConfig::exposure`](crate::SensorConfig::exposure)): a camera set to twice this
/// collects twice the light. 10 ms, a typical exposure for a projector-lit scene.
pub const VIRTUAL_EXPOSURE_MS: f64 = 10.0;

/// The longest exposure the virtual camera takes (milliseconds).
pub const VIRTUAL_MAX_EXPOSURE_MS: f64 = 10_000.0;

/// The virtual rig's projector ([`Projector`]).
#[derive(Debug, Clone)]
pub struct VirtualProjector {
    state: Arc<Mutex<DeviceState>>,
    size: (u32, u32),
}

/// The virtual rig's turntable ([`Turntable`]).
#[derive(Debug, Clone)]
pub struct VirtualTurntable {
    state: Arc<Mutex<DeviceState>>,
}

impl VirtualCamera {
    /// The view the camera sees now (cast on first use after the turntable moved).
    pub fn current_view(&mut self) -> Result<Arc<View>, SimError> {
        let (angle, moves) = {
            let st = lock(&self.state);
            (st.motor_angle_deg, st.moves)
        };
        let mut cache = lock(&self.cache);
        if let Some((m, v)) = &cache.view
            && *m == moves
        {
            return Ok(v.clone());
        }
        let v = Arc::new(self.rig.view(angle, cache.views_cast)?);
        cache.views_cast += 1;
        cache.frames_in_view = 0;
        cache.view = Some((moves, v.clone()));
        Ok(v)
    }
}

impl Camera for VirtualCamera {
    fn frame_size(&self) -> (u32, u32) {
        let s = self.rig.config.camera.size;
        (s.width, s.height)
    }

    fn capture(&mut self) -> Result<GreyImage, RigError> {
        let view = self.current_view()?;
        let (frame, stale, keep_last) = {
            let mut cache = lock(&self.cache);
            let frame = cache.frames_in_view;
            cache.frames_in_view += 1;
            let index = cache.captures;
            cache.captures += 1;
            let stale_captures = &lock(&self.state).faults.stale_captures;
            let stale = stale_captures.contains(&index);
            let keep_last = !stale_captures.is_empty();
            (
                frame,
                stale.then(|| cache.last.clone()).flatten(),
                keep_last,
            )
        };
        if let Some(last) = stale {
            return Ok(last);
        }
        // The previous image only while the current one settles: each is a whole image.
        let (shown, previous, settling) = {
            let st = lock(&self.state);
            let settling = st.settling();
            let previous = settling.and(st.previous.clone());
            (st.shown.clone(), previous, settling)
        };
        let scale = self.exposure_ms / VIRTUAL_EXPOSURE_MS;
        let render = |img: Option<&GreyImage>| -> Result<GreyImage, RigError> {
            match img {
                Some(img) => Ok(view.capture_exposed(img, frame, scale)?),
                // Nothing shown yet: the projector is dark.
                None => {
                    let radiance = view.geometry.render_fn(
                        |_, _| 0.0,
                        ProjectorSampling::Nearest,
                        &view.render.illumination,
                    );
                    Ok(view.expose_scaled(radiance, frame, scale)?)
                }
            }
        };
        let image = match settling {
            None => render(shown.as_ref())?,
            Some(Settling::Late) => render(previous.as_ref())?,
            Some(Settling::Mixed) => {
                let (old, new) = (render(previous.as_ref())?, render(shown.as_ref())?);
                let split = new.height() / 2;
                splice_rows(&old, &new, split)
            }
        };
        // The frame kept for a stale capture only when one is asked for.
        if keep_last {
            lock(&self.cache).last = Some(image.clone());
        }
        Ok(image)
    }

    /// The colour frame of what the projector shows now ([`View::capture_colour`] at the
    /// camera's exposure), counted as a capture as [`Camera::capture`] counts them. A show
    /// still settling ([`DeviceFaults`]: late or mixed) is seen as the previous image whole.
    fn capture_colour(&mut self) -> Result<ColourImage, RigError> {
        let view = self.current_view()?;
        let frame = {
            let mut cache = lock(&self.cache);
            let frame = cache.frames_in_view;
            cache.frames_in_view += 1;
            cache.captures += 1;
            frame
        };
        let shown = {
            let st = lock(&self.state);
            if st.settling().is_some() {
                st.previous.clone()
            } else {
                st.shown.clone()
            }
        };
        // Nothing shown yet: the projector is dark.
        let image = match shown {
            Some(image) => image,
            None => GreyImage::filled_u8(
                view.geometry.projector_width as usize,
                view.geometry.projector_height as usize,
                0,
            )?,
        };
        let scale = self.exposure_ms / VIRTUAL_EXPOSURE_MS;
        Ok(view.capture_colour_exposed(&image, frame, scale)?)
    }

    /// Scales the sensor's exposure by `exposure_ms /` [`VIRTUAL_EXPOSURE_MS`]: photon noise,
    /// saturation and the black level follow.
    fn set_exposure_ms(&mut self, exposure_ms: f64) -> Result<(), RigError> {
        if !(exposure_ms.is_finite() && exposure_ms > 0.0 && exposure_ms <= VIRTUAL_MAX_EXPOSURE_MS)
        {
            return Err(RigError::InvalidParameter {
                name: "exposure_ms".to_owned(),
                reason: format!(
                    "{exposure_ms} is not an exposure the virtual camera takes (0 to {VIRTUAL_MAX_EXPOSURE_MS} ms)"
                ),
            });
        }
        self.exposure_ms = exposure_ms;
        Ok(())
    }

    fn exposure_ms(&self) -> Option<f64> {
        Some(self.exposure_ms)
    }
}

impl Projector for VirtualProjector {
    fn image_size(&self) -> (u32, u32) {
        self.size
    }

    fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
        let size = image.size();
        if (size.width, size.height) != self.size {
            return Err(RigError::ImageSize {
                what: "projector image".to_owned(),
                expected_width: self.size.0,
                expected_height: self.size.1,
                width: size.width,
                height: size.height,
            });
        }
        let mut st = lock(&self.state);
        let show = st.shows;
        st.shows += 1;
        st.previous = st.shown.replace(image.clone());
        st.settling = if st.faults.late_shows.contains(&show) {
            Some((Settling::Late, std::time::Instant::now()))
        } else if st.faults.mixed_shows.contains(&show) {
            Some((Settling::Mixed, std::time::Instant::now()))
        } else {
            None
        };
        Ok(())
    }
}

impl VirtualProjector {
    /// Tells the devices to lie as `faults` says (shows and captures counted from now on
    /// as from the devices' start: the counts are not reset).
    pub fn set_faults(&mut self, faults: DeviceFaults) {
        lock(&self.state).faults = faults;
    }
}

/// The rows `0..split` of `top` above the rows of `bottom` below them (two images of one size
/// and depth; `bottom` whole otherwise).
fn splice_rows(top: &GreyImage, bottom: &GreyImage, split: usize) -> GreyImage {
    fn splice<T: sl_codec::Sample>(
        top: &Frame<T>,
        bottom: &Frame<T>,
        split: usize,
    ) -> Option<Frame<T>> {
        let w = bottom.width();
        let mut data = bottom.data().to_vec();
        let n = (split * w).min(data.len()).min(top.data().len());
        data[..n].copy_from_slice(&top.data()[..n]);
        Frame::new(w, bottom.height(), data).ok()
    }
    let spliced = match (top, bottom) {
        (GreyImage::U8(t), GreyImage::U8(b)) => splice(t, b, split).map(GreyImage::U8),
        (GreyImage::U16(t), GreyImage::U16(b)) => splice(t, b, split).map(GreyImage::U16),
        _ => None,
    };
    spliced.unwrap_or_else(|| bottom.clone())
}

impl Turntable for VirtualTurntable {
    fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError> {
        if !angle_deg.is_finite() {
            return Err(RigError::Device {
                device: "turntable".to_owned(),
                reason: format!("cannot rotate to {angle_deg} degrees"),
            });
        }
        let mut st = lock(&self.state);
        if st.motor_angle_deg != angle_deg {
            st.motor_angle_deg = angle_deg;
            st.moves += 1;
        }
        Ok(angle_deg)
    }

    fn angle_deg(&mut self) -> Result<f64, RigError> {
        Ok(lock(&self.state).motor_angle_deg)
    }
}
