//! The virtual rig with an object a person can re-place: its camera, projector and turntable
//! behind `sl-rig`'s traits, as real devices are, and the hand that lays the object on its
//! side between two placements. A scan on devices ([`scan_devices`](crate::scan_devices)) runs
//! on it unchanged, with the rig itself as the [`ScanOperator`].
//!
//! The devices delegate to `sl_sim`'s virtual camera, projector and turntable; re-placing the
//! object replaces them by the devices of the same rig looking at the new scene (sharing its
//! cast camera rays), with the image shown and the turntable angle carried over.

use std::sync::{Arc, Mutex, MutexGuard};

use sl_rig::{Camera, GreyImage, Projector, RigError, Turntable};
use sl_sim::{Scene, VirtualCamera, VirtualProjector, VirtualRig, VirtualTurntable};

use crate::{ScanError, ScanOperator};

#[derive(Debug)]
struct Shared {
    rig: VirtualRig,
    scenes: Vec<Scene>,
    camera: VirtualCamera,
    projector: VirtualProjector,
    turntable: VirtualTurntable,
    shown: Option<GreyImage>,
    angle_deg: f64,
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // Every field is replaced whole, so a poisoned lock still holds a consistent state.
    shared
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A virtual rig whose object can be laid on its side: the devices and the hand share one
/// state. Clones share it too.
#[derive(Debug, Clone)]
pub struct VirtualObjectRig {
    shared: Arc<Mutex<Shared>>,
}

impl VirtualObjectRig {
    /// The rig `rig` with its scene as the first placement.
    pub fn new(rig: VirtualRig) -> Self {
        let (camera, projector, turntable) = rig.devices();
        let scenes = vec![rig.scene().clone()];
        Self {
            shared: Arc::new(Mutex::new(Shared {
                rig,
                scenes,
                camera,
                projector,
                turntable,
                shown: None,
                angle_deg: 0.0,
            })),
        }
    }

    /// The camera, the projector and the turntable, looking at whatever placement is current.
    pub fn devices(&self) -> (ObjectCamera, ObjectProjector, ObjectTurntable) {
        (
            ObjectCamera(self.shared.clone()),
            ObjectProjector(self.shared.clone()),
            ObjectTurntable(self.shared.clone()),
        )
    }

    /// The scene of every placement so far, the current one last.
    pub fn scenes(&self) -> Vec<Scene> {
        lock(&self.shared).scenes.clone()
    }

    /// The rig looking at the current placement.
    pub fn rig(&self) -> VirtualRig {
        lock(&self.shared).rig.clone()
    }

    /// Lays the object on its side ([`Scene::laid_on_side`]): from now on the devices see
    /// the new placement.
    ///
    /// # Errors
    /// [`ScanError::Sim`] when the scene cannot be turned; the devices' when the image shown
    /// or the turntable angle cannot be carried over.
    pub fn lay_on_side(&self) -> Result<(), ScanError> {
        let mut s = lock(&self.shared);
        let laid = s.rig.scene().laid_on_side()?;
        let rig = s.rig.with_scene(laid.clone())?;
        let (camera, mut projector, mut turntable) = rig.devices();
        if let Some(img) = &s.shown {
            projector.show(img)?;
        }
        turntable.rotate_to(s.angle_deg)?;
        s.rig = rig;
        s.scenes.push(laid);
        s.camera = camera;
        s.projector = projector;
        s.turntable = turntable;
        Ok(())
    }
}

/// The rig lays its object on its side before each placement after the first.
impl ScanOperator for VirtualObjectRig {
    fn replace(&mut self, _next: usize, _total: usize) -> Result<(), ScanError> {
        self.lay_on_side()
    }
}

/// The camera of a [`VirtualObjectRig`].
#[derive(Debug, Clone)]
pub struct ObjectCamera(Arc<Mutex<Shared>>);

/// The projector of a [`VirtualObjectRig`].
#[derive(Debug, Clone)]
pub struct ObjectProjector(Arc<Mutex<Shared>>);

/// The turntable of a [`VirtualObjectRig`].
#[derive(Debug, Clone)]
pub struct ObjectTurntable(Arc<Mutex<Shared>>);

impl Camera for ObjectCamera {
    fn frame_size(&self) -> (u32, u32) {
        lock(&self.0).camera.frame_size()
    }

    fn capture(&mut self) -> Result<GreyImage, RigError> {
        lock(&self.0).camera.capture()
    }
}

impl Projector for ObjectProjector {
    fn image_size(&self) -> (u32, u32) {
        lock(&self.0).projector.image_size()
    }

    fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
        let mut s = lock(&self.0);
        s.projector.show(image)?;
        s.shown = Some(image.clone());
        Ok(())
    }
}

impl Turntable for ObjectTurntable {
    fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError> {
        let mut s = lock(&self.0);
        let reached = s.turntable.rotate_to(angle_deg)?;
        s.angle_deg = reached;
        Ok(reached)
    }

    fn angle_deg(&mut self) -> Result<f64, RigError> {
        lock(&self.0).turntable.angle_deg()
    }
}
