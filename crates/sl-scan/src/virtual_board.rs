//! The virtual rig with a board that moves: a hand-held board going through a seeded list of
//! poses ([`sl_sim::random_board_poses`]), then standing on the turntable, seen through the
//! device traits as real devices are.
//!
//! The devices delegate to `sl_sim`'s virtual camera, projector and turntable; moving the
//! board replaces them by the devices of the same rig looking at the new scene (sharing its
//! cast camera rays), with the image shown and the turntable angle carried over.

use std::sync::{Arc, Mutex, MutexGuard};

use nalgebra::Isometry3;
use sl_rig::{Camera, GreyImage, Projector, RigError, Turntable};
use sl_sim::{
    BoardPoseConfig, Checkerboard, RigConfig, Scene, SceneObject, SecondCamera, VirtualCamera,
    VirtualProjector, VirtualRig, VirtualTurntable, random_board_poses,
};

use crate::calibration_auto::BoardMover;
use crate::calibration_capture::CaptureError;

/// Poses drawn per pose asked for: the spares replace poses the capture refuses.
const SPARE_POSE_FACTOR: usize = 3;

/// Where the virtual board is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoardPlacement {
    /// Held in front of the camera at `T_cam_board`.
    Held(Isometry3<f64>),
    /// Standing on the turntable ([`Scene::board_on_table`]).
    OnTable,
}

#[derive(Debug)]
struct Shared {
    rig: VirtualRig,
    board: Checkerboard,
    poses: Vec<Isometry3<f64>>,
    next: usize,
    placement: BoardPlacement,
    camera: VirtualCamera,
    projector: VirtualProjector,
    turntable: VirtualTurntable,
    shown: Option<GreyImage>,
    angle_deg: f64,
    /// The second camera of a binocular rig: where it stands, its rig (the same scene seen
    /// from it) and its device.
    second: Option<(SecondCamera, VirtualRig, VirtualCamera)>,
}

impl Shared {
    fn place(&mut self, placement: BoardPlacement) -> Result<(), CaptureError> {
        let scene = match placement {
            BoardPlacement::OnTable => Scene::board_on_table(self.board),
            BoardPlacement::Held(t_cam_board) => {
                // The board object of the on-table scene (shape and texture), held instead.
                let on_table = Scene::board_on_table(self.board);
                let Some(b) = on_table.objects.into_iter().next() else {
                    return Err(CaptureError::sim("the board scene is empty"));
                };
                Scene::new().with(SceneObject::in_camera(
                    "board",
                    b.shape,
                    b.texture,
                    t_cam_board,
                ))
            }
        };
        let rig = self
            .rig
            .with_scene(scene.clone())
            .map_err(CaptureError::sim)?;
        let (camera, mut projector, mut turntable) = match &mut self.second {
            None => rig.devices(),
            Some((second, right_rig, right_camera)) => {
                let right = right_rig
                    .with_scene(scene.seen_from(second))
                    .map_err(CaptureError::sim)?;
                let (camera, right, projector, turntable) =
                    rig.binocular_devices(&right).map_err(CaptureError::sim)?;
                *right_camera = right;
                (camera, projector, turntable)
            }
        };
        if let Some(img) = &self.shown {
            projector.show(img)?;
        }
        turntable.rotate_to(self.angle_deg)?;
        self.camera = camera;
        self.projector = projector;
        self.turntable = turntable;
        self.placement = placement;
        Ok(())
    }
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // Every field is replaced whole, so a poisoned lock still holds a consistent state.
    shared
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// A virtual rig whose board moves: the devices and the board's mover share one state.
#[derive(Debug, Clone)]
pub struct VirtualBoardRig {
    shared: Arc<Mutex<Shared>>,
}

impl VirtualBoardRig {
    /// The rig of `config` with `board` held at the first of the poses `poses` draws
    /// (`poses.count` poses are planned, with spares for refused ones).
    pub fn new(
        config: RigConfig,
        board: Checkerboard,
        poses: &BoardPoseConfig,
    ) -> Result<Self, CaptureError> {
        let spares = BoardPoseConfig {
            count: poses.count.max(1) * SPARE_POSE_FACTOR,
            ..*poses
        };
        let planned = random_board_poses(&config, &board, &spares).map_err(CaptureError::sim)?;
        let first = *planned
            .first()
            .ok_or_else(|| CaptureError::param("poses", "no board pose drawn"))?;
        let rig =
            VirtualRig::new(config, Scene::board_on_table(board)).map_err(CaptureError::sim)?;
        let (camera, projector, turntable) = rig.devices();
        let mut shared = Shared {
            rig,
            board,
            poses: planned,
            next: 0,
            placement: BoardPlacement::OnTable,
            camera,
            projector,
            turntable,
            shown: None,
            angle_deg: 0.0,
            second: None,
        };
        shared.place(BoardPlacement::Held(first))?;
        Ok(Self {
            shared: Arc::new(Mutex::new(shared)),
        })
    }

    /// The same rig with the second camera `second` (binocular structured light): its
    /// [`VirtualBoardRig::right_camera`] sees the board wherever it is moved.
    ///
    /// # Errors
    /// The simulator's, when the second camera's rig cannot be built.
    pub fn with_second_camera(self, second: SecondCamera) -> Result<Self, CaptureError> {
        {
            let mut s = lock(&self.shared);
            let config = s.rig.config().seen_from(&second);
            let right_rig = VirtualRig::new(config, Scene::board_on_table(s.board))
                .map_err(CaptureError::sim)?;
            let (camera, _, _) = right_rig.devices();
            s.second = Some((second, right_rig, camera));
            let placement = s.placement;
            s.place(placement)?;
        }
        Ok(self)
    }

    /// The second camera's device, when the rig has one ([`VirtualBoardRig::with_second_camera`]).
    pub fn right_camera(&self) -> Option<BoardRightCamera> {
        lock(&self.shared)
            .second
            .as_ref()
            .map(|_| BoardRightCamera {
                shared: self.shared.clone(),
            })
    }

    /// The rig (its configuration is the truth a calibration is compared with).
    pub fn rig(&self) -> VirtualRig {
        lock(&self.shared).rig.clone()
    }

    /// Where the board is now.
    pub fn placement(&self) -> BoardPlacement {
        lock(&self.shared).placement
    }

    /// The camera, the projector, the turntable and the board's mover, sharing one state.
    pub fn devices(
        &self,
    ) -> (
        BoardCamera,
        BoardProjector,
        BoardTurntable,
        VirtualBoardMover,
    ) {
        let s = || self.shared.clone();
        (
            BoardCamera { shared: s() },
            BoardProjector { shared: s() },
            BoardTurntable { shared: s() },
            VirtualBoardMover { shared: s() },
        )
    }
}

/// The camera of a [`VirtualBoardRig`].
#[derive(Debug, Clone)]
pub struct BoardCamera {
    shared: Arc<Mutex<Shared>>,
}

/// The second camera of a binocular [`VirtualBoardRig`].
#[derive(Debug, Clone)]
pub struct BoardRightCamera {
    shared: Arc<Mutex<Shared>>,
}

impl Camera for BoardRightCamera {
    fn frame_size(&self) -> (u32, u32) {
        lock(&self.shared)
            .second
            .as_ref()
            .map_or((0, 0), |(_, _, c)| c.frame_size())
    }

    fn capture(&mut self) -> Result<GreyImage, RigError> {
        match &mut lock(&self.shared).second {
            Some((_, _, camera)) => camera.capture(),
            None => Err(RigError::Device {
                device: "right camera".to_owned(),
                reason: "the virtual board rig has no second camera".to_owned(),
            }),
        }
    }
}

/// The projector of a [`VirtualBoardRig`].
#[derive(Debug, Clone)]
pub struct BoardProjector {
    shared: Arc<Mutex<Shared>>,
}

/// The turntable of a [`VirtualBoardRig`].
#[derive(Debug, Clone)]
pub struct BoardTurntable {
    shared: Arc<Mutex<Shared>>,
}

/// Moves the board of a [`VirtualBoardRig`] ([`BoardMover`]): to the next planned pose, or
/// onto the turntable.
#[derive(Debug, Clone)]
pub struct VirtualBoardMover {
    shared: Arc<Mutex<Shared>>,
}

impl Camera for BoardCamera {
    fn frame_size(&self) -> (u32, u32) {
        lock(&self.shared).camera.frame_size()
    }

    fn capture(&mut self) -> Result<GreyImage, RigError> {
        lock(&self.shared).camera.capture()
    }
}

impl Projector for BoardProjector {
    fn image_size(&self) -> (u32, u32) {
        lock(&self.shared).projector.image_size()
    }

    fn show(&mut self, image: &GreyImage) -> Result<(), RigError> {
        let mut s = lock(&self.shared);
        s.projector.show(image)?;
        s.shown = Some(image.clone());
        Ok(())
    }
}

impl Turntable for BoardTurntable {
    fn rotate_to(&mut self, angle_deg: f64) -> Result<f64, RigError> {
        let mut s = lock(&self.shared);
        let reached = s.turntable.rotate_to(angle_deg)?;
        s.angle_deg = reached;
        Ok(reached)
    }

    fn angle_deg(&mut self) -> Result<f64, RigError> {
        lock(&self.shared).turntable.angle_deg()
    }
}

impl BoardMover for VirtualBoardMover {
    fn moves_itself(&self) -> bool {
        true
    }

    fn next_pose(&mut self) -> Result<(), CaptureError> {
        let mut s = lock(&self.shared);
        s.next += 1;
        let Some(&pose) = s.poses.get(s.next) else {
            return Err(CaptureError::param(
                "poses",
                format!(
                    "the virtual board has no pose left ({} planned)",
                    s.poses.len()
                ),
            ));
        };
        s.place(BoardPlacement::Held(pose))
    }

    fn onto_turntable(&mut self) -> Result<(), CaptureError> {
        lock(&self.shared).place(BoardPlacement::OnTable)
    }
}
