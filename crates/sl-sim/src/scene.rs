//! Scene description: shapes, textures, and where each object is mounted.

use std::sync::Arc;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::shape::TriMesh;

use crate::footprint::Footprint;
use crate::{Checkerboard, SimError};

/// Geometry of one object, in its own frame (millimetres).
#[derive(Debug, Clone)]
pub enum Shape {
    /// A flat rectangle in the object's `z = 0` plane spanning `[x_min, x_max] × [y_min, y_max]`;
    /// seen from either side. Intersected in closed form.
    Rectangle {
        /// Lowest `x` (mm).
        x_min: f64,
        /// Lowest `y` (mm).
        y_min: f64,
        /// Highest `x` (mm).
        x_max: f64,
        /// Highest `y` (mm).
        y_max: f64,
    },
    /// A sphere centred on the origin.
    Sphere {
        /// Radius (mm).
        radius: f64,
    },
    /// A box centred on the origin, edges along the axes.
    Cuboid {
        /// Full side lengths along `x`, `y`, `z` (mm).
        size: Vector3<f64>,
    },
    /// A closed cylinder centred on the origin, axis along `z`, from `z = -height/2` to
    /// `z = height/2`.
    Cylinder {
        /// Radius (mm).
        radius: f64,
        /// Height (mm).
        height: f64,
    },
    /// A triangle mesh (vertices in mm); shared, so cloning a scene is cheap.
    Mesh(Arc<TriMesh>),
}

impl Shape {
    /// A rectangle of `width × height` mm centred on the origin of the `z = 0` plane.
    pub fn rectangle(width: f64, height: f64) -> Self {
        Self::Rectangle {
            x_min: -width / 2.0,
            y_min: -height / 2.0,
            x_max: width / 2.0,
            y_max: height / 2.0,
        }
    }

    /// A triangle mesh from vertices (mm) and triangles (indices into `vertices`).
    ///
    /// Fails with [`SimError::InvalidScene`] naming `name` when the mesh is empty, an index is
    /// out of range or a vertex is not finite.
    pub fn mesh(
        name: &str,
        vertices: Vec<Point3<f64>>,
        triangles: Vec<[u32; 3]>,
    ) -> Result<Self, SimError> {
        if triangles.is_empty() {
            return Err(SimError::scene(name, "the mesh has no triangle"));
        }
        if let Some(i) = vertices
            .iter()
            .position(|v| !v.coords.iter().all(|c| c.is_finite()))
        {
            return Err(SimError::scene(name, format!("vertex {i} is not finite")));
        }
        let n = vertices.len();
        if let Some((t, tri)) = triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
        {
            return Err(SimError::scene(
                name,
                format!("triangle {t} {tri:?} refers to a vertex beyond the {n} vertices"),
            ));
        }
        let mesh = TriMesh::new(vertices, triangles)
            .map_err(|e| SimError::scene(name, format!("{e:?}")))?;
        Ok(Self::Mesh(Arc::new(mesh)))
    }

    fn validate(&self, name: &str) -> Result<(), SimError> {
        let positive = |what: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(SimError::scene(
                    name,
                    format!("{what} {v} is not a positive length"),
                ))
            }
        };
        match self {
            Self::Rectangle {
                x_min,
                y_min,
                x_max,
                y_max,
            } => {
                positive("rectangle width", x_max - x_min)?;
                positive("rectangle height", y_max - y_min)
            }
            Self::Sphere { radius } => positive("sphere radius", *radius),
            Self::Cuboid { size } => {
                positive("box size x", size.x)?;
                positive("box size y", size.y)?;
                positive("box size z", size.z)
            }
            Self::Cylinder { radius, height } => {
                positive("cylinder radius", *radius)?;
                positive("cylinder height", *height)
            }
            Self::Mesh(_) => Ok(()),
        }
    }
}

/// The Lambertian albedo (fraction of light reflected, in `[0, 1]`) over an object's surface.
#[derive(Debug, Clone, PartialEq)]
pub enum Texture {
    /// The same albedo everywhere.
    Uniform(f64),
    /// A solid 3-D checker in the object frame: cubes of side `period_mm` alternate between
    /// `dark` and `light` (a texture that varies on every shape, to test albedo robustness).
    Checker3d {
        /// Side of a checker cube (mm).
        period_mm: f64,
        /// Albedo of the cubes containing the origin's diagonal neighbours.
        dark: f64,
        /// Albedo of the other cubes.
        light: f64,
    },
    /// A printed checkerboard in the object's `z = 0` plane (the object frame is the board
    /// frame).
    Board(Checkerboard),
    /// The same colour everywhere: an RGB albedo, each channel in `[0, 1]`.
    Colour([f64; 3]),
    /// Solid 3-D colour patches in the object frame: cubes of side `cell_mm` centred on the
    /// points `(i, j, k) · cell_mm` (so the origin is a patch's centre, and a plane through
    /// it crosses the middle of its patches), cube `(i, j, k)` of colour
    /// `colours[(i + j + k) mod n]`. Two cubes that share a face differ by one in
    /// `i + j + k`, so with two colours or more they never share a colour.
    ColourCells {
        /// Side of a cube (mm).
        cell_mm: f64,
        /// The RGB albedos (each channel in `[0, 1]`), at least one.
        colours: Vec<[f64; 3]>,
    },
}

/// Weights of the red, green and blue albedos in the grey albedo of a colour texture
/// ([`Texture::albedo_at`]): ITU-R BT.601's luma, the weights of OpenCV's `COLOR_RGB2GRAY`
/// that the decoders read colour frames with, so that a grey render is the luma of the colour
/// render.
pub const LUMA_WEIGHTS: [f64; 3] = [0.299, 0.587, 0.114];

/// The grey albedo of an RGB albedo: its luma ([`LUMA_WEIGHTS`]).
pub fn luma_of(rgb: &[f64; 3]) -> f64 {
    LUMA_WEIGHTS[0] * rgb[0] + LUMA_WEIGHTS[1] * rgb[1] + LUMA_WEIGHTS[2] * rgb[2]
}

impl Texture {
    /// The (grey) albedo at `p`, a point of the surface in the object frame (mm): the luma
    /// ([`luma_of`]) of the colour textures' RGB albedo, which the grey renders use.
    pub fn albedo_at(&self, p: &Point3<f64>) -> f64 {
        match self {
            Self::Colour(_) | Self::ColourCells { .. } => luma_of(&self.albedo_rgb_at(p)),
            Self::Uniform(a) => *a,
            Self::Checker3d {
                period_mm,
                dark,
                light,
            } => {
                let s = (p.x / period_mm).floor()
                    + (p.y / period_mm).floor()
                    + (p.z / period_mm).floor();
                if s.rem_euclid(2.0) < 0.5 {
                    *dark
                } else {
                    *light
                }
            }
            Self::Board(b) => b.albedo_at(p.x, p.y),
        }
    }

    /// The RGB albedo at `p`, a point of the surface in the object frame (mm): `[a, a, a]`
    /// for the grey textures (albedo `a`).
    ///
    /// ```
    /// use nalgebra::Point3;
    /// use sl_sim::Texture;
    /// let red = Texture::Colour([0.8, 0.2, 0.1]);
    /// assert_eq!(red.albedo_rgb_at(&Point3::origin()), [0.8, 0.2, 0.1]);
    /// // Its grey albedo is its luma: 0.299 · 0.8 + 0.587 · 0.2 + 0.114 · 0.1.
    /// assert!((red.albedo_at(&Point3::origin()) - 0.368).abs() < 1e-12);
    /// assert_eq!(Texture::Uniform(0.5).albedo_rgb_at(&Point3::origin()), [0.5; 3]);
    /// ```
    pub fn albedo_rgb_at(&self, p: &Point3<f64>) -> [f64; 3] {
        match self {
            Self::Colour(rgb) => *rgb,
            Self::ColourCells { cell_mm, colours } => {
                let n = colours.len().max(1) as f64;
                let cell = |v: f64| (v / cell_mm + 0.5).floor();
                let s = cell(p.x) + cell(p.y) + cell(p.z);
                let k = s.rem_euclid(n);
                let k = if k.is_finite() { k as usize } else { 0 };
                colours.get(k).copied().unwrap_or([0.0; 3])
            }
            Self::Uniform(_) | Self::Checker3d { .. } | Self::Board(_) => [self.albedo_at(p); 3],
        }
    }

    /// Whether the texture has colour (its RGB albedo is not grey everywhere by construction).
    pub fn is_colour(&self) -> bool {
        matches!(self, Self::Colour(_) | Self::ColourCells { .. })
    }

    /// The RGB albedo averaged over a camera sub-sample's footprint, as
    /// [`Texture::albedo_over`] averages the grey one (`[a, a, a]` for the grey textures).
    pub(crate) fn albedo_rgb_over(&self, fp: &Footprint) -> [f64; 3] {
        match self {
            Self::Colour(rgb) => *rgb,
            Self::ColourCells { cell_mm, colours } => cells_over(fp, *cell_mm, colours),
            Self::Uniform(_) | Self::Checker3d { .. } | Self::Board(_) => [self.albedo_over(fp); 3],
        }
    }

    /// The albedo averaged over a camera sub-sample's footprint (object frame, mm): what the
    /// sub-sample's square integrates, without point sampling's bias at the texture's edges.
    pub(crate) fn albedo_over(&self, fp: &Footprint) -> f64 {
        match self {
            Self::Uniform(a) => *a,
            Self::Checker3d {
                period_mm,
                dark,
                light,
            } => {
                // Dark where floor(x/p) + floor(y/p) + floor(z/p) is even, i.e. where the
                // product of the three axes' square waves is +1.
                let product: f64 = (0..3)
                    .map(|k| fp.axis(k).mean_square_wave(*period_mm, None))
                    .product();
                light + (dark - light) * (0.5 * (1.0 + product)).clamp(0.0, 1.0)
            }
            Self::Board(b) => b.albedo_over(fp),
            Self::Colour(_) | Self::ColourCells { .. } => luma_of(&self.albedo_rgb_over(fp)),
        }
    }

    /// Whether the albedo varies over the surface (so that a footprint matters).
    pub(crate) fn is_uniform(&self) -> bool {
        matches!(self, Self::Uniform(_) | Self::Colour(_))
    }

    fn validate(&self, name: &str) -> Result<(), SimError> {
        let check = |a: f64| {
            if (0.0..=1.0).contains(&a) {
                Ok(())
            } else {
                Err(SimError::scene(
                    name,
                    format!("albedo {a} is not in [0, 1]"),
                ))
            }
        };
        match self {
            Self::Uniform(a) => check(*a),
            Self::Checker3d {
                period_mm,
                dark,
                light,
            } => {
                if !(period_mm.is_finite() && *period_mm > 0.0) {
                    return Err(SimError::scene(
                        name,
                        format!("checker period {period_mm} is not positive"),
                    ));
                }
                check(*dark)?;
                check(*light)
            }
            Self::Board(b) => b
                .validate()
                .map_err(|e| SimError::scene(name, e.to_string())),
            Self::Colour(rgb) => rgb.iter().try_for_each(|&a| check(a)),
            Self::ColourCells { cell_mm, colours } => {
                if !(cell_mm.is_finite() && *cell_mm > 0.0) {
                    return Err(SimError::scene(
                        name,
                        format!("colour cell side {cell_mm} is not positive"),
                    ));
                }
                if colours.is_empty() {
                    return Err(SimError::scene(
                        name,
                        "colour cells need at least one colour",
                    ));
                }
                colours.iter().flatten().try_for_each(|&a| check(a))
            }
        }
    }
}

/// [`Texture::ColourCells`] averaged over the footprint `fp`: along each axis the share of the
/// footprint in each cell (exact, [`crate::footprint`]'s trapezoid law), the three axes taken
/// as independent (as [`Texture::Checker3d`]'s product of square waves is: exact wherever one
/// cell boundary crosses the footprint), the shares of the colour indices `(i + j + k) mod n`
/// convolved from the axes' shares. A footprint across more than [`MAX_CELLS_ACROSS`] cells
/// along an axis (a grazing view) takes that axis as uniform over the indices.
fn cells_over(fp: &Footprint, cell_mm: f64, colours: &[[f64; 3]]) -> [f64; 3] {
    let n = colours.len();
    if n == 0 || !(cell_mm.is_finite() && cell_mm > 0.0) {
        return [0.0; 3];
    }
    let mut shares = vec![0.0f64; n];
    if let Some(first) = shares.first_mut() {
        *first = 1.0;
    }
    for axis in 0..3 {
        let spread = fp.axis(axis);
        let reach = spread.half_a + spread.half_b;
        let mut axis_shares = vec![0.0f64; n];
        if reach > MAX_CELLS_ACROSS * cell_mm || !spread.centre.is_finite() {
            axis_shares.iter_mut().for_each(|s| *s = 1.0 / n as f64);
        } else {
            let first = ((spread.centre - reach) / cell_mm + 0.5).floor() as i64;
            let last = ((spread.centre + reach) / cell_mm + 0.5).floor() as i64;
            for cell in first..=last {
                let lo = (cell as f64 - 0.5) * cell_mm;
                let share = spread.mean_box(lo, lo + cell_mm);
                if let Some(s) = axis_shares.get_mut(cell.rem_euclid(n as i64) as usize) {
                    *s += share;
                }
            }
        }
        let mut next = vec![0.0f64; n];
        for (a, &sa) in shares.iter().enumerate() {
            for (b, &sb) in axis_shares.iter().enumerate() {
                if let Some(o) = next.get_mut((a + b) % n) {
                    *o += sa * sb;
                }
            }
        }
        shares = next;
    }
    let total: f64 = shares.iter().sum();
    let mut rgb = [0.0; 3];
    for (share, colour) in shares.iter().zip(colours) {
        for (o, c) in rgb.iter_mut().zip(colour) {
            *o += share * c / total.max(f64::MIN_POSITIVE);
        }
    }
    rgb
}

/// Cells a footprint may cross along one axis before [`Texture::ColourCells`] takes the axis
/// as uniform: as the square waves' `MAX_STRIPES`, a view so grazing that no detector
/// resolves the cells.
const MAX_CELLS_ACROSS: f64 = 32.0;

/// What an object is fixed to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mount {
    /// Stands on the turntable: its pose is `T_table_object` and it turns with the table.
    Turntable,
    /// Fixed in the camera frame (e.g. a board held in front of the rig): its pose is
    /// `T_cam_object`.
    Camera,
}

/// A specular (Blinn–Phong) lobe on top of an object's Lambertian albedo: the projector's
/// light mirrored toward the camera, as a glossy paint, a plastic or a polished metal shows
/// it. Where the surface's normal halves the directions to the camera and to the projector,
/// the object reflects `strength` times the light a white (albedo 1) Lambertian surface would
/// there; away from that direction the lobe falls off as `(n · h)^exponent`. A highlight
/// several times brighter than white paper saturates a camera exposed for the paper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gloss {
    /// The lobe's peak, in units of a white Lambertian surface's radiance.
    pub strength: f64,
    /// Its sharpness, the Blinn–Phong exponent (20: satin; 200: glossy plastic).
    pub exponent: f64,
}

impl Gloss {
    /// The lobe's weight `strength · (n · h)^exponent` for the unit normal `n` and the unit
    /// half vector `h` between the directions to the camera and to the projector.
    pub fn lobe(&self, n_dot_h: f64) -> f64 {
        if n_dot_h <= 0.0 {
            0.0
        } else {
            self.strength * n_dot_h.powf(self.exponent)
        }
    }

    /// Checks that the strength is ≥ 0 and the exponent ≥ 1, both finite.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] naming `gloss.strength` or `gloss.exponent`.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(self.strength.is_finite() && self.strength >= 0.0) {
            return Err(SimError::param(
                "gloss.strength",
                format!("{} is not a strength ≥ 0", self.strength),
            ));
        }
        if !(self.exponent.is_finite() && self.exponent >= 1.0) {
            return Err(SimError::param(
                "gloss.exponent",
                format!("{} is not an exponent ≥ 1", self.exponent),
            ));
        }
        Ok(())
    }
}

/// The surfaces the virtual rig scans, from the easy to the difficult ([`Scene::finished`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Finish {
    /// Bright matte plaster: albedo [`DEFAULT_ALBEDO`], no gloss.
    #[default]
    Matte,
    /// A black part: albedo [`DARK_ALBEDO`], no gloss. Exposed for white paper, its fringes
    /// are a few grey levels deep.
    Dark,
    /// A glossy grey plastic: albedo [`GLOSSY_ALBEDO`] with a lobe of strength
    /// [`GLOSSY_STRENGTH`] and exponent [`GLOSSY_EXPONENT`], whose highlights saturate a camera
    /// exposed for white paper.
    Glossy,
    /// Matte colour patches: [`Texture::ColourCells`] of [`COLOURED_CELL_MM`] cubes in the
    /// colours [`COLOURED_ALBEDOS`] (red, green, blue, yellow; lumas 0.42–0.75, so the
    /// fringes decode as on bright plaster), no gloss. For colour scans.
    Coloured,
}

/// Side (mm) of the colour patches of [`Finish::Coloured`]: 25 mm, several on any preset
/// object, each wide enough (some 70 camera pixels at the working distance) for its colour to
/// be judged away from its edges. With the patches centred on the object's origin no flat
/// face of a preset lies on a patch boundary, where rounding would pick either colour: the
/// plane's `z = 0` and a mesh's cut bottom are mid-patch, the box's faces at ±50 mm (2 cells)
/// and the cylinder's caps at ±60 mm (2.4 cells) too.
pub const COLOURED_CELL_MM: f64 = 25.0;

/// RGB albedos of [`Finish::Coloured`]'s patches: a red, a green, a blue and a yellow paint,
/// none darker in luma than 0.42 (the red; the blue 0.47) so that the geometry decodes as on
/// plaster.
pub const COLOURED_ALBEDOS: [[f64; 3]; 4] = [
    [0.85, 0.25, 0.2],
    [0.3, 0.75, 0.3],
    [0.35, 0.45, 0.9],
    [0.85, 0.8, 0.25],
];

/// Albedo of [`Finish::Dark`]: black plastic or anodised aluminium reflect 3–5 %.
pub const DARK_ALBEDO: f64 = 0.04;
/// Albedo of [`Finish::Glossy`].
pub const GLOSSY_ALBEDO: f64 = 0.4;
/// Lobe strength of [`Finish::Glossy`]: the highlight is 6 times a white Lambertian surface.
pub const GLOSSY_STRENGTH: f64 = 6.0;
/// Lobe exponent of [`Finish::Glossy`]: a highlight ~15° wide, as on a glossy plastic.
pub const GLOSSY_EXPONENT: f64 = 60.0;

impl Finish {
    /// The names `slscan scan --finish` takes.
    pub const NAMES: [&str; 4] = ["matte", "dark", "glossy", "coloured"];

    /// The finish called `name` (one of [`Finish::NAMES`]).
    pub fn named(name: &str) -> Option<Self> {
        match name {
            "matte" => Some(Self::Matte),
            "dark" => Some(Self::Dark),
            "glossy" => Some(Self::Glossy),
            "coloured" | "colored" => Some(Self::Coloured),
            _ => None,
        }
    }

    /// Its name, as [`Finish::named`] takes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Matte => "matte",
            Self::Dark => "dark",
            Self::Glossy => "glossy",
            Self::Coloured => "coloured",
        }
    }

    /// The texture and the gloss of the finish.
    pub fn surface(self) -> (Texture, Option<Gloss>) {
        match self {
            Self::Matte => (Texture::Uniform(DEFAULT_ALBEDO), None),
            Self::Dark => (Texture::Uniform(DARK_ALBEDO), None),
            Self::Glossy => (
                Texture::Uniform(GLOSSY_ALBEDO),
                Some(Gloss {
                    strength: GLOSSY_STRENGTH,
                    exponent: GLOSSY_EXPONENT,
                }),
            ),
            Self::Coloured => (
                Texture::ColourCells {
                    cell_mm: COLOURED_CELL_MM,
                    colours: COLOURED_ALBEDOS.to_vec(),
                },
                None,
            ),
        }
    }
}

/// One object of a scene.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// Name, used in messages and in the ground truth.
    pub name: String,
    /// Geometry in the object frame.
    pub shape: Shape,
    /// Albedo over the surface.
    pub texture: Texture,
    /// What the object is fixed to.
    pub mount: Mount,
    /// Pose of the object frame in the mount frame: `T_table_object` or `T_cam_object`.
    pub pose: Isometry3<f64>,
    /// A specular lobe over the albedo; `None` (the constructors' default) for a matte
    /// object.
    pub gloss: Option<Gloss>,
}

impl SceneObject {
    /// An object standing on the turntable at `T_table_object`.
    pub fn on_table(
        name: &str,
        shape: Shape,
        texture: Texture,
        t_table_object: Isometry3<f64>,
    ) -> Self {
        Self {
            name: name.to_owned(),
            shape,
            texture,
            mount: Mount::Turntable,
            pose: t_table_object,
            gloss: None,
        }
    }

    /// An object fixed in the camera frame at `T_cam_object`.
    pub fn in_camera(
        name: &str,
        shape: Shape,
        texture: Texture,
        t_cam_object: Isometry3<f64>,
    ) -> Self {
        Self {
            name: name.to_owned(),
            shape,
            texture,
            mount: Mount::Camera,
            pose: t_cam_object,
            gloss: None,
        }
    }

    /// A printed checkerboard whose board frame is at `pose` in the mount frame.
    pub fn board(name: &str, board: Checkerboard, mount: Mount, pose: Isometry3<f64>) -> Self {
        let (x_min, y_min, x_max, y_max) = board.extent();
        Self {
            name: name.to_owned(),
            shape: Shape::Rectangle {
                x_min,
                y_min,
                x_max,
                y_max,
            },
            texture: Texture::Board(board),
            mount,
            pose,
            gloss: None,
        }
    }
}

/// Default albedo of the preset objects: bright matte plaster.
pub const DEFAULT_ALBEDO: f64 = 0.8;

/// A set of objects in front of the rig.
///
/// # Table frame
/// Objects mounted on the turntable are placed in the `table` frame: origin on the axis at the
/// table top, `z` up along the axis, `x` towards the camera's right and `y` away from the
/// camera when the table is at angle 0 (see [`RigConfig`](crate::RigConfig)).
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// The objects.
    pub objects: Vec<SceneObject>,
}

/// Rotation taking the `table` frame to the frame of an upright panel facing the camera at
/// angle 0: panel `x` = table `x`, panel `y` = table `-z` (down), panel `z` = table `y` (away
/// from the camera, "into the board" as the board convention wants).
pub fn upright_facing_camera() -> UnitQuaternion<f64> {
    let m = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

impl Scene {
    /// The same scene for the second camera `second` (with [`RigConfig::seen_from`]): objects
    /// fixed to the camera (a plate held in front of the rig) stay where they are in the first
    /// camera's frame; objects on the turntable move with the rig's `t_cam_table` already.
    ///
    /// [`RigConfig::seen_from`]: crate::RigConfig::seen_from
    #[must_use]
    pub fn seen_from(&self, second: &crate::SecondCamera) -> Scene {
        let t_second_cam = second.t_cam_second.inverse();
        let mut scene = self.clone();
        for o in &mut scene.objects {
            if o.mount == Mount::Camera {
                o.pose = t_second_cam * o.pose;
            }
        }
        scene
    }

    /// An empty scene.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds an object.
    pub fn with(mut self, object: SceneObject) -> Self {
        self.objects.push(object);
        self
    }

    /// Checks every object (positive sizes, albedos in `[0, 1]`, valid boards).
    pub fn validate(&self) -> Result<(), SimError> {
        if self.objects.is_empty() {
            return Err(SimError::scene("scene", "the scene has no object"));
        }
        for o in &self.objects {
            o.shape.validate(&o.name)?;
            o.texture.validate(&o.name)?;
            if let Some(g) = &o.gloss {
                g.validate()?;
            }
        }
        Ok(())
    }

    /// The scene with every object on the turntable given the surface `finish` (boards and
    /// objects fixed to the camera keep theirs).
    #[must_use]
    pub fn finished(mut self, finish: Finish) -> Self {
        for o in &mut self.objects {
            if o.mount == Mount::Turntable && !matches!(o.texture, Texture::Board(_)) {
                let (texture, gloss) = finish.surface();
                o.texture = texture;
                o.gloss = gloss;
            }
        }
        self
    }

    /// The names [`Scene::named`] knows, in the order a help text lists them.
    pub const NAMES: [&str; 5] = ["plane", "sphere", "dumbbell", "box", "cylinder"];

    /// The built-in scene called `name` (one of [`Scene::NAMES`]: `box` is
    /// [`Scene::cuboid`]), or `None`.
    ///
    /// ```
    /// use sl_sim::Scene;
    /// assert!(Scene::NAMES.iter().all(|n| Scene::named(n).is_some()));
    /// assert!(Scene::named("teapot").is_none());
    /// ```
    #[must_use]
    pub fn named(name: &str) -> Option<Self> {
        Some(match name {
            "plane" => Self::plane(),
            "sphere" => Self::sphere(),
            "dumbbell" => Self::dumbbell(),
            "box" => Self::cuboid(),
            "cylinder" => Self::cylinder(),
            _ => return None,
        })
    }

    /// A 300 × 200 mm white plane standing upright on the axis, facing the camera at angle 0.
    pub fn plane() -> Self {
        let pose =
            Isometry3::from_parts(Translation3::new(0.0, 0.0, 60.0), upright_facing_camera());
        Self::new().with(SceneObject::on_table(
            "plane",
            Shape::rectangle(300.0, 200.0),
            Texture::Uniform(DEFAULT_ALBEDO),
            pose,
        ))
    }

    /// A sphere of radius 50 mm standing on the table, centred on the axis.
    pub fn sphere() -> Self {
        Self::new().with(SceneObject::on_table(
            "sphere",
            Shape::Sphere { radius: 50.0 },
            Texture::Uniform(DEFAULT_ALBEDO),
            Isometry3::translation(0.0, 0.0, 50.0),
        ))
    }

    /// Two spheres of radius 25 mm whose centres are [`DUMBBELL_CENTRE_DISTANCE_MM`] apart,
    /// side by side at 60 mm above the table (the sphere-bar test of VDI/VDE 2634).
    pub fn dumbbell() -> Self {
        let half = DUMBBELL_CENTRE_DISTANCE_MM / 2.0;
        let ball = |name: &str, x: f64| {
            SceneObject::on_table(
                name,
                Shape::Sphere { radius: 25.0 },
                Texture::Uniform(DEFAULT_ALBEDO),
                Isometry3::translation(x, 0.0, 60.0),
            )
        };
        Self::new()
            .with(ball("sphere_left", -half))
            .with(ball("sphere_right", half))
    }

    /// A 100 mm cube standing on the table, turned 30° about the axis so that the camera sees
    /// two of its sides and its top.
    pub fn cuboid() -> Self {
        let pose = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 50.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians()),
        );
        Self::new().with(SceneObject::on_table(
            "box",
            Shape::Cuboid {
                size: Vector3::new(100.0, 100.0, 100.0),
            },
            Texture::Uniform(DEFAULT_ALBEDO),
            pose,
        ))
    }

    /// A cylinder of radius 40 mm and height 120 mm standing on the table, with a 3-D checker
    /// texture.
    pub fn cylinder() -> Self {
        Self::new().with(SceneObject::on_table(
            "cylinder",
            Shape::Cylinder {
                radius: 40.0,
                height: 120.0,
            },
            Texture::Checker3d {
                period_mm: 15.0,
                dark: 0.3,
                light: DEFAULT_ALBEDO,
            },
            Isometry3::translation(0.0, 0.0, 60.0),
        ))
    }

    /// A checkerboard standing upright on the turntable, facing the camera at angle 0, its
    /// grid centred on the axis at 60 mm above the table (the turntable-axis calibration
    /// target).
    pub fn board_on_table(board: Checkerboard) -> Self {
        let s = board.square_mm;
        let w = f64::from(board.inner_cols - 1) * s;
        let h = f64::from(board.inner_rows - 1) * s;
        // Board frame origin (first inner corner) so that the grid centre is at (0, 0, 60).
        let pose = Isometry3::from_parts(
            Translation3::new(-w / 2.0, 0.0, 60.0 + h / 2.0),
            upright_facing_camera(),
        );
        Self::new().with(SceneObject::board("board", board, Mount::Turntable, pose))
    }

    /// A triangle mesh standing on the turntable: scaled by `scale` (e.g. 1000 for a mesh in
    /// metres), turned so that `up` (in the mesh's own axes) is the table's `z`, then moved so
    /// that its lowest point touches the table and its bounding box is centred on the axis.
    pub fn standing_mesh(
        name: &str,
        vertices: &[Point3<f64>],
        triangles: Vec<[u32; 3]>,
        scale: f64,
        up: Vector3<f64>,
        texture: Texture,
    ) -> Result<Self, SimError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(SimError::param(
                "mesh scale",
                format!("{scale} is not positive"),
            ));
        }
        let rot = UnitQuaternion::rotation_between(&up, &Vector3::z()).unwrap_or_else(|| {
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        let moved: Vec<Point3<f64>> = vertices
            .iter()
            .map(|v| rot * Point3::from(v.coords * scale))
            .collect();
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for v in &moved {
            lo = lo.inf(&v.coords);
            hi = hi.sup(&v.coords);
        }
        let shift = Vector3::new(-(lo.x + hi.x) / 2.0, -(lo.y + hi.y) / 2.0, -lo.z);
        let placed: Vec<Point3<f64>> = moved.iter().map(|v| v + shift).collect();
        let shape = Shape::mesh(name, placed, triangles)?;
        Ok(Self::new().with(SceneObject::on_table(
            name,
            shape,
            texture,
            Isometry3::identity(),
        )))
    }
}

/// Units of the vertices of a mesh file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MeshUnits {
    /// Millimetres (scale 1).
    Millimetres,
    /// Metres (scale 1000), as the Stanford scans.
    Metres,
    /// Metres when the bounding box's diagonal is below [`AUTO_METRES_BELOW`] units (no
    /// turntable object is 10 mm across; few are 10 m), else millimetres.
    #[default]
    Auto,
}

/// Bounding-box diagonal below which [`MeshUnits::Auto`] takes a mesh to be in metres.
pub const AUTO_METRES_BELOW: f64 = 10.0;

impl Scene {
    /// A PLY triangle mesh (faces, or a Stanford range grid: see `sl_cloud::read_ply_mesh`)
    /// standing on the turntable as [`Scene::standing_mesh`] places it, with `up` its own
    /// vertical axis (`y` for the Stanford scans) and a uniform [`DEFAULT_ALBEDO`]. The object
    /// is named after the file stem.
    pub fn ply_mesh(
        path: &std::path::Path,
        units: MeshUnits,
        up: Vector3<f64>,
    ) -> Result<Self, SimError> {
        let mesh = sl_cloud::read_ply_mesh(path)?;
        let name = path
            .file_stem()
            .map_or_else(|| "mesh".to_owned(), |s| s.to_string_lossy().into_owned());
        let scale = match units {
            MeshUnits::Millimetres => 1.0,
            MeshUnits::Metres => 1000.0,
            MeshUnits::Auto => {
                let mut lo = Vector3::repeat(f64::INFINITY);
                let mut hi = Vector3::repeat(f64::NEG_INFINITY);
                for v in &mesh.vertices {
                    lo = lo.inf(&v.coords);
                    hi = hi.sup(&v.coords);
                }
                if (hi - lo).norm() < AUTO_METRES_BELOW {
                    1000.0
                } else {
                    1.0
                }
            }
        };
        Self::standing_mesh(
            &name,
            &mesh.vertices,
            mesh.triangles,
            scale,
            up,
            Texture::Uniform(DEFAULT_ALBEDO),
        )
    }
}

/// Distance between the two sphere centres of [`Scene::dumbbell`] (mm).
pub const DUMBBELL_CENTRE_DISTANCE_MM: f64 = 120.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upright_rotation_maps_axes() {
        let r = upright_facing_camera();
        assert!((r * Vector3::x() - Vector3::x()).norm() < 1e-15);
        assert!((r * Vector3::y() + Vector3::z()).norm() < 1e-15);
        assert!((r * Vector3::z() - Vector3::y()).norm() < 1e-15);
    }

    #[test]
    fn presets_validate() {
        for s in [
            Scene::plane(),
            Scene::sphere(),
            Scene::dumbbell(),
            Scene::cuboid(),
            Scene::cylinder(),
        ] {
            s.validate().unwrap();
        }
        Scene::board_on_table(Checkerboard::default())
            .validate()
            .unwrap();
        assert!(Scene::new().validate().is_err());
    }

    /// The grey albedo of a colour texture is its luma by BT.601's weights (summing to 1:
    /// white stays white), at every point; the coloured finish's patches are all brighter
    /// than 0.4 in luma and never share a colour with a face neighbour.
    #[test]
    fn colour_textures_are_grey_by_their_luma() {
        assert!((LUMA_WEIGHTS.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        let (texture, gloss) = Finish::Coloured.surface();
        assert!(gloss.is_none() && texture.is_colour());
        for rgb in COLOURED_ALBEDOS {
            let luma = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
            assert!(luma > 0.4, "{rgb:?}: luma {luma}");
        }
        let c = COLOURED_CELL_MM;
        for k in 0..200 {
            let t = f64::from(k);
            let p = Point3::new(37.1 * t.sin() * 3.0, 11.3 * t - 900.0, 53.0 * t.cos() * 2.0);
            let rgb = texture.albedo_rgb_at(&p);
            let want = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2];
            assert!((texture.albedo_at(&p) - want).abs() < 1e-15);
            // A face neighbour's patch has another colour.
            for axis in 0..3 {
                let mut q = p;
                q[axis] += c;
                assert_ne!(texture.albedo_rgb_at(&q), rgb);
            }
        }
        // Patches are centred on the origin: ±0.49 cell is the origin's patch.
        let origin = texture.albedo_rgb_at(&Point3::origin());
        assert_eq!(origin, COLOURED_ALBEDOS[0]);
        assert_eq!(
            texture.albedo_rgb_at(&Point3::new(0.49 * c, -0.49 * c, 0.0)),
            origin
        );
        assert_eq!(
            texture.albedo_rgb_at(&Point3::new(0.51 * c, 0.0, 0.0)),
            COLOURED_ALBEDOS[1]
        );
        assert_eq!(
            Texture::Uniform(0.3).albedo_rgb_at(&Point3::origin()),
            [0.3; 3]
        );
        // Out-of-range colours are refused, naming the object.
        let bad = Texture::ColourCells {
            cell_mm: 10.0,
            colours: vec![[0.5, 1.2, 0.0]],
        };
        let err = bad.validate("vase").unwrap_err().to_string();
        assert!(err.contains("vase") && err.contains("1.2"), "{err}");
        assert!(
            Texture::ColourCells {
                cell_mm: 10.0,
                colours: vec![]
            }
            .validate("v")
            .is_err()
        );
        assert!(Texture::Colour([0.1, -0.1, 0.0]).validate("v").is_err());
        assert_eq!(Finish::named("coloured"), Some(Finish::Coloured));
        assert_eq!(Finish::Coloured.name(), "coloured");
    }

    /// The footprint average of colour patches equals a dense average of the point colours
    /// over the parallelogram where one patch boundary crosses it (exact there), and within
    /// a few percent of the colour difference where a corner does (the axes are averaged as
    /// independent).
    #[test]
    fn colour_patches_average_over_a_footprint() {
        let (texture, _) = Finish::Coloured.surface();
        let c = COLOURED_CELL_MM;
        let dense = |fp: &Footprint| -> [f64; 3] {
            let m = 300;
            let mut acc = [0.0; 3];
            for i in 0..m {
                for j in 0..m {
                    let t = (f64::from(i) + 0.5) / f64::from(m) - 0.5;
                    let u = (f64::from(j) + 0.5) / f64::from(m) - 0.5;
                    let p = fp.centre + fp.edge_x * t + fp.edge_y * u;
                    let rgb = texture.albedo_rgb_at(&p);
                    for k in 0..3 {
                        acc[k] += rgb[k] / f64::from(m * m);
                    }
                }
            }
            acc
        };
        // Across the boundary x = c/2 only (y and z mid-patch), tilted edges.
        for (dx, ex, ey) in [
            (
                0.3,
                Vector3::new(1.0, 0.4, 0.0),
                Vector3::new(0.5, -1.0, 0.2),
            ),
            (
                -0.7,
                Vector3::new(2.0, 0.0, 0.3),
                Vector3::new(0.0, 1.5, 0.0),
            ),
            (
                0.05,
                Vector3::new(0.2, 0.1, 0.0),
                Vector3::new(-0.3, 0.9, 0.1),
            ),
        ] {
            let fp = Footprint {
                centre: Point3::new(0.5 * c + dx, 0.1 * c, -0.2 * c),
                edge_x: ex,
                edge_y: ey,
            };
            let got = texture.albedo_rgb_over(&fp);
            let want = dense(&fp);
            for k in 0..3 {
                // A 300 × 300 grid resolves the boundary to 1/300 of the footprint.
                assert!((got[k] - want[k]).abs() < 0.004, "{got:?} vs {want:?}");
            }
            assert!((texture.albedo_over(&fp) - luma_of(&got)).abs() < 1e-15);
        }
        // At a corner of four patches.
        let fp = Footprint {
            centre: Point3::new(0.5 * c + 0.2, 0.5 * c - 0.3, 0.0),
            edge_x: Vector3::new(1.5, 0.3, 0.0),
            edge_y: Vector3::new(-0.2, 1.2, 0.0),
        };
        let (got, want) = (texture.albedo_rgb_over(&fp), dense(&fp));
        for k in 0..3 {
            assert!((got[k] - want[k]).abs() < 0.03, "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn mesh_rejects_bad_indices() {
        let v = vec![
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        ];
        assert!(Shape::mesh("m", v.clone(), vec![[0, 1, 3]]).is_err());
        assert!(Shape::mesh("m", v, vec![[0, 1, 2]]).is_ok());
    }
}
