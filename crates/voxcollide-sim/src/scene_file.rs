//! Scene files (docs/design.md §8): a TOML description of the bodies, their contacts, the schedule and
//! the output, read with serde so that every error names the file, the line, the column and the
//! key.
//!
//! [`SceneFile::read`] parses and checks a file: TOML syntax, unknown keys (an error, never
//! ignored), value types and ranges, a body's required keys for its kind, unique body names,
//! contacts that name existing and distinct bodies, meshes that exist. What passes is a
//! [`SceneFile`] whose lengths are still in the file's [`Units`]; [`SceneFile::metres`] converts.
//!
//! ```
//! use voxcollide_sim::scene_file::{BodyKind, SceneFile};
//!
//! let text = r#"
//! units = "mm"
//! [[body]]
//! name = "tissue"
//! kind = "soft"
//! shape = { box = [80, 80, 15] }
//! spacing = 2.5
//! [[body]]
//! name = "probe"
//! kind = "rigid"
//! shape = { sphere = 10 }
//! spacing = 2.0
//! motion = [{ t = 0.0, position = [0, 0, 20] }, { t = 1.0, position = [0, 0, 12] }]
//! [[contact]]
//! a = "probe"
//! b = "tissue"
//! "#;
//! let scene = SceneFile::parse("indent.toml", text)?;
//! assert_eq!(scene.bodies.len(), 2);
//! assert_eq!(scene.bodies[1].kind, BodyKind::Rigid);
//! assert_eq!(scene.contacts[0].a, 1); // the index of "probe"
//!
//! let typo = SceneFile::parse("indent.toml", "[[body]]\nname = \"x\"\nkind = \"soft\"\nspacingg = 1\n");
//! assert!(typo.unwrap_err().to_string().starts_with("indent.toml:4:1: body[0].spacingg:"));
//! # Ok::<(), voxcollide::Error>(())
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde::de::{self, Deserializer, Visitor};
use toml::Spanned;
use voxcollide::Error;

/// The unit of every length in a file and its meshes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    /// Millimetres (the default).
    #[default]
    Mm,
    /// Centimetres.
    Cm,
    /// Metres.
    M,
    /// The paper's layer units (docs/design.md §1: the tissue layer is 8 wide): lengths with no
    /// physical size. They are computed as metres, so that the paper's constants carry over
    /// unchanged (`k = 0.4·E·h`), and printed and drawn as "layer units", never as metres, with
    /// volumes in cubic layer units, never in millilitres.
    Layer,
}

impl Units {
    /// Metres per unit.
    #[must_use]
    pub fn metres(self) -> f64 {
        match self {
            Units::Mm => 1e-3,
            Units::Cm => 1e-2,
            Units::M | Units::Layer => 1.0,
        }
    }

    /// Whether a length in these units is a physical one (millimetres, centimetres, metres),
    /// so that a volume can be given in millilitres.
    #[must_use]
    pub fn is_physical(self) -> bool {
        self != Units::Layer
    }

    /// The unit's symbol, as printed after a length (`"layer units"` for [`Units::Layer`],
    /// whose name in a file is `"layer"`).
    #[must_use]
    pub fn symbol(self) -> &'static str {
        match self {
            Units::Mm => "mm",
            Units::Cm => "cm",
            Units::M => "m",
            Units::Layer => "layer units",
        }
    }
}

/// A value that is either `"auto"` (the program chooses) or given.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Auto<T> {
    /// `"auto"`.
    #[default]
    Auto,
    /// A value from the file.
    Value(T),
}

impl<'de> Deserialize<'de> for Auto<f64> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Auto<f64>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"auto\" or a number")
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Auto<f64>, E> {
                if s == "auto" {
                    Ok(Auto::Auto)
                } else {
                    Err(E::invalid_value(de::Unexpected::Str(s), &self))
                }
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Auto<f64>, E> {
                Ok(Auto::Value(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Auto<f64>, E> {
                Ok(Auto::Value(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Auto<f64>, E> {
                Ok(Auto::Value(x as f64))
            }
        }
        d.deserialize_any(V)
    }
}

/// `[time]`: the schedule.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Time {
    /// Simulated seconds of the schedule (or [`steps`](Self::steps)); default 1 s.
    pub duration: Option<f64>,
    /// Steps of the schedule, instead of a duration.
    pub steps: Option<u64>,
    /// The time step in seconds, or `"auto"` (half the integrator's stability bound).
    #[serde(default)]
    pub dt: Auto<f64>,
    /// After the schedule, go on until the bodies come to rest.
    #[serde(default)]
    pub settle: bool,
    /// A cap on all steps; reaching it unsettled is reported, not an error.
    #[serde(default = "default_max_steps")]
    pub max_steps: u64,
    /// The integrator (docs/design.md §12): the paper's semi-implicit Euler, `"explicit"`, or
    /// `"implicit"`: backward Euler ([`crate::integrator::implicit`]). A file that names none
    /// gets the implicit one in physical units (millimetres, the default, centimetres or
    /// metres) where every contact is the surface contact, and the explicit one in the paper's
    /// layer units or with a voxel-model response; [`Time::default`] is explicit.
    #[serde(default)]
    pub integrator: IntegratorSpec,
}

/// `[time] integrator` (docs/design.md §12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum IntegratorSpec {
    /// The paper's semi-implicit (symplectic) Euler, its step within the stability bound.
    #[default]
    Explicit,
    /// Backward Euler, whose step is not bound by stability ([`crate::integrator::implicit`]).
    Implicit,
}

impl IntegratorSpec {
    /// The name a scene file gives it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            IntegratorSpec::Explicit => "explicit",
            IntegratorSpec::Implicit => "implicit",
        }
    }
}

/// `[world]` (docs/design.md §13): gravity, and which axis pictures draw upward.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldSpec {
    /// The acceleration of gravity in m/s², in the scene's axes (whatever `units` says);
    /// `None`: none.
    #[serde(default)]
    pub gravity: Option<[f64; 3]>,
    /// Which axis pictures draw upward (default z).
    #[serde(default)]
    pub up: Axis,
}

/// An axis of the scene: `"x"`, `"y"` or `"z"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z (the default up).
    #[default]
    Z,
}

impl Axis {
    /// Its index: 0, 1 or 2.
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// `reference = { gravity }` (docs/design.md §13): the shape given was measured under this
/// gravity (m/s², the scene's axes), with the body's held vertices held.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reference {
    /// The gravity the shape was measured under.
    pub gravity: [f64; 3],
}

/// A material's model (docs/design.md §12).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MaterialModel {
    /// The paper's spring lattice (Poisson's ratio 1/4 whatever the file says), the default.
    #[default]
    Springs,
    /// Finite elements that honour `poisson` ([`crate::material::neo_hookean`]).
    NeoHookean,
}

fn default_max_steps() -> u64 {
    200_000
}

impl Default for Time {
    fn default() -> Time {
        Time {
            duration: None,
            steps: None,
            dt: Auto::Auto,
            settle: false,
            max_steps: default_max_steps(),
            integrator: IntegratorSpec::Explicit,
        }
    }
}

/// What a body is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BodyKind {
    /// A volumetric lattice of springs inside a closed surface, or a tetrahedral mesh.
    Soft,
    /// A closed surface of springs (inflatable).
    Shell,
    /// Moves only as its keyframes drive it.
    Rigid,
}

/// An implant's style.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ImplantStyle {
    /// Round: rotationally symmetric.
    #[default]
    Round,
    /// Anatomical (teardrop): fuller at the bottom.
    Anatomical,
}

/// An implant's profile: its projection as a fraction of its base width, as catalogues group
/// them. For 300 mL, a high profile is about 111 mm wide and 45 mm high, a low one about 135 mm
/// wide and 30 mm high.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Profile {
    /// `"low"`: projection 0.22 × base.
    Low,
    /// `"moderate"`: projection 0.30 × base.
    Moderate,
    /// `"high"`: projection 0.40 × base.
    High,
    /// `"extra-high"`: projection 0.48 × base.
    ExtraHigh,
}

impl Profile {
    /// The projection over the base width.
    pub fn ratio(self) -> f64 {
        match self {
            Profile::Low => 0.22,
            Profile::Moderate => 0.30,
            Profile::High => 0.40,
            Profile::ExtraHigh => 0.48,
        }
    }
}

/// An `implant = { … }` table as written: a projection or a profile.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ImplantTable {
    volume_ml: f64,
    base_mm: f64,
    projection_mm: Option<f64>,
    profile: Option<Profile>,
    #[serde(default)]
    style: ImplantStyle,
}

/// [`Shape::Implant`]'s fields from its table, the projection from the profile where one is
/// named.
fn implant_fields<'de, D: Deserializer<'de>>(d: D) -> Result<(f64, f64, f64, ImplantStyle), D::Error> {
    let t = ImplantTable::deserialize(d)?;
    let projection = match (t.projection_mm, t.profile) {
        (Some(p), None) => p,
        (None, Some(profile)) => profile.ratio() * t.base_mm,
        (Some(_), Some(_)) => {
            return Err(de::Error::custom("give `projection_mm` or `profile`, not both"));
        }
        (None, None) => {
            return Err(de::Error::custom(
                "missing `projection_mm` (mm) or `profile` (\"low\", \"moderate\", \"high\" or \"extra-high\")",
            ));
        }
    };
    Ok((t.volume_ml, t.base_mm, projection, t.style))
}

/// `between = { outer, inner, min, max }` (docs/design.md §14): the tissue between the skin as
/// scanned and the chest wall, inside a box.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Between {
    /// The skin: an open sheet or a closed surface, facing away from the patient (resolved
    /// against the scene file's folder).
    pub outer: PathBuf,
    /// The chest wall, behind `outer`, facing away from the patient.
    pub inner: PathBuf,
    /// The box's lowest corner (file units and axes).
    pub min: [f64; 3],
    /// Its highest corner.
    pub max: [f64; 3],
}

/// A built-in shape, centred at the origin (but `between`, which lies where its surfaces do).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum Shape {
    /// `box = [x, y, z]`: sizes.
    Box([f64; 3]),
    /// `sphere = r`.
    Sphere(f64),
    /// `ellipsoid = [rx, ry, rz]`.
    Ellipsoid([f64; 3]),
    /// `cylinder = { radius, height }`, axis z.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Height.
        height: f64,
    },
    /// `implant = { volume_ml, base_mm, projection_mm, style }`, or `profile` (a
    /// [`Profile`] name) in place of `projection_mm`: the projection that profile gives the
    /// base.
    #[serde(deserialize_with = "implant_fields")]
    Implant {
        /// Volume in millilitres.
        volume_ml: f64,
        /// Base width in millimetres.
        base_mm: f64,
        /// Projection in millimetres.
        projection_mm: f64,
        /// Round (default) or anatomical.
        #[serde(default)]
        style: ImplantStyle,
    },
    /// `between = { outer, inner, min, max }`: a breast from a scan ([`Between`]).
    Between(Between),
}

/// A tissue's published parameters (`material = { preset = "fat" }`, and a layer's
/// `preset`; docs/patient.md gives the sources): its Young's modulus, and Poisson's ratio 0.49
/// and density 1000 kg/m³ for all (nearly incompressible, as breast models take them). Keys
/// given beside a preset override it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Breast fat: 3.25 kPa (Samani, Zubovits and Plewes 2007, 169 ex vivo samples, small
    /// strain).
    Fat,
    /// Fibroglandular tissue: 3.24 kPa (Samani et al. 2007).
    Gland,
    /// Breast skin: 4 kPa (Mîra et al. 2018, identified in vivo from MRI in three postures).
    Skin,
    /// Pectoralis major: 80 kPa (its sternocostal part in Zhang et al., a breast model
    /// validated against motion data).
    Muscle,
}

impl Preset {
    /// Its Young's modulus in kPa.
    #[must_use]
    pub fn young_kpa(self) -> f64 {
        match self {
            Preset::Fat => 3.25,
            Preset::Gland => 3.24,
            Preset::Skin => 4.0,
            Preset::Muscle => 80.0,
        }
    }

    /// Its Poisson's ratio.
    #[must_use]
    pub fn poisson(self) -> f64 {
        0.49
    }

    /// Its density in kg/m³.
    #[must_use]
    pub fn density(self) -> f64 {
        1000.0
    }
}

/// A material as written: every key optional, a preset's values under the keys given.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    preset: Option<Preset>,
    young_kpa: Option<f64>,
    poisson: Option<f64>,
    density: Option<f64>,
    damping: Option<f64>,
    spring_damping: Option<f64>,
    #[serde(default)]
    model: MaterialModel,
}

impl From<RawMaterial> for MaterialSpec {
    fn from(r: RawMaterial) -> MaterialSpec {
        MaterialSpec {
            young_kpa: r
                .young_kpa
                .or(r.preset.map(Preset::young_kpa))
                .unwrap_or(MaterialSpec::DEFAULT.young_kpa),
            poisson: r.poisson.or(r.preset.map(Preset::poisson)).unwrap_or(MaterialSpec::DEFAULT.poisson),
            density: r.density.or(r.preset.map(Preset::density)).unwrap_or(MaterialSpec::DEFAULT.density),
            damping: r.damping.unwrap_or(MaterialSpec::DEFAULT.damping),
            spring_damping: r.spring_damping,
            model: r.model,
            preset: r.preset,
        }
    }
}

/// A body's material.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(from = "RawMaterial")]
pub struct MaterialSpec {
    /// Young's modulus in kPa (default 3, soft tissue).
    pub young_kpa: f64,
    /// Poisson's ratio, `0 <= ν < 0.5` (default 0.45).
    pub poisson: f64,
    /// Density in kg/m³ (default 1000).
    pub density: f64,
    /// Damping ratio, `>= 0` (default 0.1): of the viscous term, and of the springs' own
    /// damping unless [`spring_damping`](Self::spring_damping) is given.
    pub damping: f64,
    /// Damping ratio of the damping along each spring (default: `damping`).
    pub spring_damping: Option<f64>,
    /// The model: `"springs"` (the default: the paper's lattice, ν = 1/4) or `"neo-hookean"`
    /// (tetrahedra that honour `poisson`: [`crate::material::neo_hookean`]).
    pub model: MaterialModel,
    /// The tissue preset its values came from, where one was named.
    pub preset: Option<Preset>,
}

impl MaterialSpec {
    /// A body's material where its file gives none, and each key's value where the file's
    /// material leaves it out: 3 kPa, ν = 0.45, 1000 kg/m³, damping 0.1, the paper's springs.
    pub const DEFAULT: MaterialSpec = MaterialSpec {
        young_kpa: 3.0,
        poisson: 0.45,
        density: 1000.0,
        damping: 0.1,
        spring_damping: None,
        model: MaterialModel::Springs,
        preset: None,
    };

    /// The Poisson's ratio its model gives: `poisson` for finite elements, 1/4 for the paper's
    /// spring lattice whatever `poisson` says.
    #[must_use]
    pub fn model_poisson(&self) -> f64 {
        match self.model {
            MaterialModel::Springs => 0.25,
            MaterialModel::NeoHookean => self.poisson,
        }
    }
}

/// The material of a shell placed on a patient's chest wall (`place`) that gives no `material`:
/// a body's default but for its modulus, 30 kPa. A body's own default, 3 kPa, is as soft as her
/// fat, and under her breast's weight such a shell crumples and passes through itself. On the
/// MakeHuman patient standing at a 6 mm spacing, a 300 mL implant counted 165 of its 299 mL twice
/// at 3 kPa, 69 mL at 10 kPa and 5 mL at 30 kPa (docs/patient.md).
pub const PLACED_SHELL_MATERIAL: MaterialSpec = MaterialSpec { young_kpa: 30.0, ..MaterialSpec::DEFAULT };

impl Default for MaterialSpec {
    fn default() -> MaterialSpec {
        MaterialSpec::DEFAULT
    }
}

/// One coordinate: exactly one of `x`, `y`, `z`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisValue {
    /// `x = v`.
    pub x: Option<f64>,
    /// `y = v`.
    pub y: Option<f64>,
    /// `z = v`.
    pub z: Option<f64>,
}

impl AxisValue {
    /// The axis (0, 1, 2) and value, when exactly one is given.
    #[must_use]
    pub fn get(&self) -> Option<(usize, f64)> {
        match (self.x, self.y, self.z) {
            (Some(v), None, None) => Some((0, v)),
            (None, Some(v), None) => Some((1, v)),
            (None, None, Some(v)) => Some((2, v)),
            _ => None,
        }
    }
}

/// Which vertices are held.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Fixed {
    /// `{ below = { z = v } }`: vertices below the plane.
    Below(AxisValue),
    /// `{ above = { z = v } }`: vertices above the plane.
    Above(AxisValue),
    /// `{ inside_box = { min = [..], max = [..] } }`.
    InsideBox {
        /// The box's minimum corner.
        min: [f64; 3],
        /// The box's maximum corner.
        max: [f64; 3],
    },
    /// `{ rim = w }`: within `w` of the body's lateral (x, y) boundary.
    Rim(f64),
    /// `{ depth = d }`: within `d` of the body's outer surface at rest (its faces where it is
    /// not held: a skin, not a chest wall or a box's side), as a skin layer over fat and gland
    /// (docs/design.md §14).
    Depth(f64),
}

/// A region of a soft body with its own stiffness, bonded to the rest: skin over fat, a
/// gland in fat. `layers = [{ region = { above = { z = 39 } }, young_kpa = 12 }]`: the
/// springs with both ends in `region` (selected as `fixed` selects vertices, at rest) take
/// that Young's modulus; later layers override earlier ones. In a `"neo-hookean"` body the
/// tetrahedra whose centres are in `region` take it, at the body's Poisson ratio; a region
/// that holds no tetrahedron's centre (thinner than a cell) is refused.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(try_from = "RawLayer")]
pub struct Layer {
    /// Where: `below`, `above`, `inside_box`, `rim` or `depth`, as for `fixed`.
    pub region: Fixed,
    /// Its Young's modulus in kPa: given, or its `preset`'s.
    pub young_kpa: f64,
}

/// A layer as written: its modulus, or a tissue preset's.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLayer {
    region: Fixed,
    young_kpa: Option<f64>,
    preset: Option<Preset>,
}

impl TryFrom<RawLayer> for Layer {
    type Error = String;
    fn try_from(r: RawLayer) -> Result<Layer, String> {
        let young_kpa = r.young_kpa.or(r.preset.map(Preset::young_kpa)).ok_or(
            "a layer needs `young_kpa` or a tissue `preset` (\"fat\", \"gland\", \"skin\" or \"muscle\")",
        )?;
        Ok(Layer { region: r.region, young_kpa })
    }
}

/// How a keyframe or a ramp is approached.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ease {
    /// At a constant rate (the default).
    #[default]
    Linear,
    /// Smoothstep: `3u² − 2u³`, starting and ending at rest.
    Smooth,
}

impl Ease {
    /// The fraction reached at `u` of the way (clamped to `0..=1`), in `f32` as the simulator's
    /// schedules compute it.
    #[must_use]
    pub fn at(self, u: f32) -> f32 {
        let u = u.clamp(0.0, 1.0);
        match self {
            Ease::Linear => u,
            Ease::Smooth => u * u * (3.0 - 2.0 * u),
        }
    }
}

/// A keyframe: where a rigid body, or a soft body's driven vertices, are at a time.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Seconds.
    pub t: f64,
    /// The body's translation at `t`.
    pub position: [f64; 3],
    /// Its rotation at `t` (degrees, x then y then z).
    #[serde(default)]
    pub rotation: [f64; 3],
    /// How it is approached from the keyframe before.
    #[serde(default)]
    pub ease: Ease,
}

/// A shell's inflation: by pressure or to a volume, ramped; or, as a tissue expander is filled,
/// by a schedule of volumes.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inflate {
    /// The final internal pressure in kPa.
    pub pressure_kpa: Option<f64>,
    /// Or the final volume in mL. With a `schedule`, its last volume.
    pub volume_ml: Option<f64>,
    /// Or `[[t, volume_ml], …]`: the volume it holds at each time (seconds, increasing),
    /// linear between them, from the volume it starts with at t = 0, held after the last. An
    /// expander only fills: the volumes do not decrease. `ramp` and `ease` are unused.
    #[serde(default)]
    pub schedule: Vec<[f64; 2]>,
    /// Seconds over which it is ramped (default 1).
    #[serde(default = "default_ramp")]
    pub ramp: f64,
    /// How it is ramped.
    #[serde(default)]
    pub ease: Ease,
}

fn default_ramp() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBody {
    name: Spanned<String>,
    kind: BodyKind,
    mesh: Option<Spanned<String>>,
    shape: Option<Spanned<Shape>>,
    spacing: Option<Spanned<f64>>,
    #[serde(default)]
    position: [f64; 3],
    #[serde(default)]
    rotation: [f64; 3],
    #[serde(default = "one")]
    scale: Spanned<f64>,
    #[serde(default = "unspanned")]
    material: Spanned<MaterialSpec>,
    #[serde(default)]
    fixed: Vec<Spanned<Fixed>>,
    #[serde(default)]
    driven: Vec<Spanned<Fixed>>,
    #[serde(default)]
    layers: Vec<Spanned<Layer>>,
    floor: Option<f64>,
    #[serde(default = "unspanned")]
    motion: Spanned<Vec<Keyframe>>,
    inflate: Option<Spanned<Inflate>>,
    reference: Option<Spanned<Reference>>,
    #[serde(default)]
    landmarks: Option<Spanned<std::collections::BTreeMap<String, [f64; 3]>>>,
    place: Option<Spanned<RawPlace>>,
}

/// `place = { under = "body.landmark", within, margin, friction }`, as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlace {
    under: String,
    within: Option<Vec<String>>,
    margin: Option<f64>,
    friction: Option<f64>,
}

/// Where a shell is placed on a patient (`place = { under = "breast.nipple" }`,
/// docs/design.md §15): its base on the chest wall of a `between` body, under one of its
/// landmarks, its apex along the wall's outward normal.
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// The `between` body whose chest wall it stands on (an index into [`SceneFile::bodies`]).
    pub body: usize,
    /// The landmark of that body it stands under.
    pub landmark: String,
    /// Landmarks of that body that its base's rim stays within (`within`, for example her
    /// breast's `medial` and `lateral` borders): where the base under `landmark` would reach
    /// past one, it moves across the wall, away from it, until its rim stands at the border
    /// (docs/patient.md, "Where the base stands").
    pub within: Vec<String>,
    /// How far past the base's rim the pocket is dissected (file units; `margin`, default
    /// [`POCKET_MARGIN_MM`]): the tissue's vertices held on the wall within the base's radius
    /// and this margin are let go.
    pub margin: f64,
    /// Coulomb's coefficient of friction between the implant and the chest wall (`friction`,
    /// default [`SMOOTH_SHELL_FRICTION`]): once the implant has filled, a vertex pressed onto
    /// the wall stays where it is while the force along the wall is at most this times the
    /// force into it.
    pub friction: f64,
    /// Whether the file pairs the implant with that body in no `[[contact]]`, so that the
    /// default contact between them (`a` the implant, `b` the tissue) was added: an implant
    /// placed in a patient's tissue with nothing to stop it would pass through her and be
    /// reported as her new shape.
    pub contact_added: bool,
}

/// The implant's friction on the chest wall when a placement gives none: a smooth silicone
/// shell's, 0.46 ± 0.11, measured sliding on the same shell (Atkins, Chau, Rosas et al. 2023,
/// "Silicone implant surface roughness, friction, and wear", Surf. Topogr.: Metrol. Prop. 11,
/// 014010; microtextured 1.20, macrotextured 2.82). Nobody we found measured it against the
/// pectoral fascia; docs/patient.md says what it does to a plan.
pub const SMOOTH_SHELL_FRICTION: f64 = 0.46;

/// The pocket's margin past an implant's base when a placement gives none, in millimetres: a
/// pocket dissected a centimetre wider than the implant, as surgeons describe it (enough for
/// the implant to sit flat, not so much that it turns).
pub const POCKET_MARGIN_MM: f64 = 10.0;

/// A default value, at no place in the file (defaults are valid, so no error points there).
fn unspanned<T: Default>() -> Spanned<T> {
    Spanned::new(0..0, T::default())
}

fn one() -> Spanned<f64> {
    Spanned::new(0..0, 1.0)
}

/// A contact's force direction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DirectionSpec {
    /// Along the line of centres (the default).
    #[default]
    Pairwise,
    /// Along the normal of the plane through the three nearest A vertices.
    PlaneNormal,
}

/// A contact's search.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SearchSpec {
    /// The 3×3×3 block within a radius (the default).
    #[default]
    Neighbours,
    /// The paper's rule: the own voxel.
    Voxel,
}

/// A contact's response: how strongly it pushes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResponseSpec {
    /// A penalty growing with depth measured to the partner's surface triangles, on both sides,
    /// stiff enough for the step and the bodies (the default): the response that holds
    /// (docs/semantics.md, "Contacts that hold"). Its search runs on the host, under the GPU
    /// world too.
    #[default]
    Surface,
    /// The voxel model's penalty: growing with depth behind the plane of the three nearest (or
    /// inside the sphere around the partner), pushing `b` out of `a` only; on the GPU too.
    Penalty,
    /// The paper's constant magnitude, bit for bit.
    Constant,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawContact {
    a: Spanned<String>,
    b: Spanned<String>,
    #[serde(default)]
    direction: DirectionSpec,
    #[serde(default)]
    search: SearchSpec,
    #[serde(default = "unspanned")]
    radius: Spanned<Auto<f64>>,
    #[serde(default = "unspanned")]
    voxel_size: Spanned<Auto<f64>>,
    #[serde(default = "unspanned")]
    magnitude: Spanned<Auto<f64>>,
    #[serde(default)]
    response: ResponseSpec,
    #[serde(default = "unspanned")]
    stiffness: Spanned<Auto<f64>>,
    #[serde(default = "unspanned")]
    gap: Spanned<Auto<f64>>,
}

/// `[output]`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Pictures and VTK frames over the run (default 12).
    #[serde(default = "default_frames")]
    pub frames: u32,
    /// Whether to write PNG pictures (default true).
    #[serde(default = "yes")]
    pub images: bool,
    /// Whether to write VTK files (default true).
    #[serde(default = "yes")]
    pub vtk: bool,
}

fn default_frames() -> u32 {
    12
}
fn yes() -> bool {
    true
}

impl Default for Output {
    fn default() -> Output {
        Output { frames: default_frames(), images: true, vtk: true }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    #[serde(default)]
    units: Units,
    #[serde(default)]
    time: Time,
    #[serde(default = "unspanned")]
    world: Spanned<WorldSpec>,
    #[serde(default)]
    body: Vec<RawBody>,
    #[serde(default)]
    contact: Vec<RawContact>,
    #[serde(default)]
    output: Output,
}

/// Where a body's geometry comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// A mesh file, resolved against the scene file's folder.
    Mesh(PathBuf),
    /// A built-in shape.
    Shape(Shape),
}

/// One `[[body]]`, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct BodySpec {
    /// Its unique name.
    pub name: String,
    /// Soft, shell or rigid.
    pub kind: BodyKind,
    /// Its mesh or shape.
    pub geometry: Geometry,
    /// Lattice spacing (soft) or surface edge length (shell, rigid shape), in file units.
    pub spacing: Option<f64>,
    /// Translation, in file units.
    pub position: [f64; 3],
    /// Rotation in degrees, x then y then z.
    pub rotation: [f64; 3],
    /// Uniform scale.
    pub scale: f64,
    /// Its material.
    pub material: MaterialSpec,
    /// Held vertices.
    pub fixed: Vec<Fixed>,
    /// Vertices of a soft body that follow `motion` (a rigid body's all do), by the same rules
    /// as `fixed`.
    pub driven: Vec<Fixed>,
    /// A soft body's regions of another stiffness.
    pub layers: Vec<Layer>,
    /// A wall: the body's free vertices are kept at `z >= floor` (file units).
    pub floor: Option<f64>,
    /// Keyframes (rigid bodies, and soft bodies' driven vertices), in ascending time.
    pub motion: Vec<Keyframe>,
    /// Inflation (shells).
    pub inflate: Option<Inflate>,
    /// A shell that starts flattened onto its base: its vertices' heights above its lowest
    /// point times this factor, in `(0, 1]`, its springs' rest lengths those of
    /// its full shape (`voxcollide compare` starts a candidate so, to fit under the tissue
    /// however close it lies; not a file key). Filled to a volume, it fills from what it
    /// holds flattened, its rest shape unchanged.
    pub flatten: Option<f64>,
    /// The gravity the shape given was measured under, in m/s² (`reference = { gravity }`):
    /// the run first finds the unloaded shape that comes to it (docs/design.md §13). `None`:
    /// the shape given is unloaded.
    pub reference: Option<[f64; 3]>,
    /// Named points (`landmarks = { nipple = [x, y, z] }`, docs/design.md §14), in name order:
    /// each moved onto the body's outer surface and carried by it through the run.
    pub landmarks: Vec<(String, [f64; 3])>,
    /// How far below its place a shell starts, its floor as far below, both rising back over
    /// its inflation ramp (file units; 0: none): where the tissue lies on the chest wall, a
    /// flattened shell starts under it and lifts it as it fills (set by `voxcollide compare`;
    /// not a file key).
    pub sink: f64,
    /// A shell placed on a patient's chest wall under a landmark (`place`, docs/design.md
    /// §15); `None`: where `position` puts it.
    pub place: Option<Placement>,
}

/// One `[[contact]]`, checked: `a` and `b` are indices into [`SceneFile::bodies`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactSpec {
    /// The indexed body (binned; the voxel model follows it).
    pub a: usize,
    /// The probing body.
    pub b: usize,
    /// Force direction.
    pub direction: DirectionSpec,
    /// Search.
    pub search: SearchSpec,
    /// Neighbour radius, in file units.
    pub radius: Auto<f64>,
    /// Voxel size, a power of two in file units.
    pub voxel_size: Auto<f64>,
    /// Penalty magnitude in newtons: the constant response's force, or the penalty's largest.
    pub magnitude: Auto<f64>,
    /// How strongly it pushes: a penalty growing with depth, or the paper's constant.
    pub response: ResponseSpec,
    /// The penalty's stiffness in newtons per metre.
    pub stiffness: Auto<f64>,
    /// How far outside A the penalty begins, in file units (0 or more).
    pub gap: Auto<f64>,
}

/// A scene file, read and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneFile {
    /// The file it was read from.
    pub path: PathBuf,
    /// The unit of its lengths.
    pub units: Units,
    /// The schedule.
    pub time: Time,
    /// Gravity, and the axis pictures draw upward.
    pub world: WorldSpec,
    /// The bodies, in file order.
    pub bodies: Vec<BodySpec>,
    /// The contacts, in file order.
    pub contacts: Vec<ContactSpec>,
    /// The output.
    pub output: Output,
    /// The file's text, to point errors found after parsing at their line.
    text: String,
}

/// 1-based line and column of byte `offset` in `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rfind('\n').map_or(before.len(), |nl| before.len() - nl - 1) + 1;
    (line, column)
}

/// The dotted path of the key whose line holds byte `offset`: the tables above it
/// (`[[body]]` counted, so `body[2]`), then the key on that line (inline tables too).
pub(crate) fn key_at(text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let mut table = String::new();
    let mut counts: Vec<(String, usize)> = Vec::new();
    let mut line_start = 0;
    for line in text.split_inclusive('\n') {
        if line_start > offset {
            break;
        }
        let trimmed = line.trim();
        let here = offset < line_start + line.len();
        if let Some(name) = trimmed.strip_prefix("[[").and_then(|t| t.split("]]").next()) {
            let name = name.trim().to_string();
            let k = match counts.iter_mut().find(|(n, _)| *n == name) {
                Some((_, c)) => {
                    *c += 1;
                    *c - 1
                }
                None => {
                    counts.push((name.clone(), 1));
                    0
                }
            };
            table = format!("{name}[{k}]");
        } else if let Some(name) = trimmed.strip_prefix('[').and_then(|t| t.split(']').next()) {
            table = name.trim().to_string();
        }
        if here {
            // The key whose value holds the offset: the inline tables and arrays open before it
            // on this line (`a = { b = [{ c = `), then the key being given.
            let mut key = inline_key(&line[..offset - line_start]);
            if !trimmed.starts_with('[') {
                // At a key itself (an unknown one): that key, under what is open before it.
                if let Some((k, _)) = line[offset - line_start..].split_once('=') {
                    let k = k.trim();
                    if !k.is_empty() && !k.contains(['{', '}', '[', ']', ',', '"']) && !key.ends_with(k) {
                        key = if key.is_empty() { k.to_string() } else { format!("{key}.{k}") };
                    }
                }
            }
            return match (table.is_empty(), key.is_empty()) {
                (true, _) => key,
                (false, true) => table,
                (false, false) => format!("{table}.{key}"),
            };
        }
        line_start += line.len();
    }
    table
}

/// The dotted key at the end of `upto`, the start of a line: `material = { poisson = 0.` gives
/// `material.poisson`, `fixed = [{ below = {` gives `fixed.below`; quoted text is skipped.
fn inline_key(upto: &str) -> String {
    let mut stack: Vec<String> = Vec::new();
    let mut leaf: Option<String> = None;
    let mut word = String::new();
    let mut chars = upto.chars().peekable();
    let mut pending: Option<String> = None; // a key whose `=` was seen, its value not yet
    while let Some(c) = chars.next() {
        match c {
            '"' | '\'' => {
                for d in chars.by_ref() {
                    if d == c {
                        break;
                    }
                }
                pending = None;
            }
            '=' => {
                pending = Some(word.trim().to_string());
                leaf = pending.clone();
                word.clear();
            }
            '{' | '[' => {
                if let Some(k) = pending.take() {
                    stack.push(k);
                } else if c == '{' {
                    stack.push(String::new()); // a table inside an array
                }
                leaf = None;
                word.clear();
            }
            '}' | ']' => {
                stack.pop();
                leaf = None;
                word.clear();
            }
            ',' => {
                leaf = None;
                pending = None;
                word.clear();
            }
            c if c.is_whitespace() && pending.is_some() => {}
            c => {
                if pending.is_some() {
                    pending = None; // the value started: a scalar
                }
                word.push(c);
            }
        }
    }
    stack.iter().filter(|k| !k.is_empty()).cloned().chain(leaf).collect::<Vec<_>>().join(".")
}

/// A body's `place`, as read, with where it stands in the text; `None` for a body not placed.
type PlaceAt = Option<(Range<usize>, RawPlace)>;

/// A scene file's text and the name it is read by: what an error names (file, line, key).
#[derive(Clone, Copy)]
struct Source<'a> {
    file: &'a str,
    text: &'a str,
}

impl Source<'_> {
    /// The error of the text at `span`, with `message`.
    fn err(self, span: Range<usize>, message: String) -> Error {
        at(self.file, self.text, span, None, message)
    }
}

/// Body `k` of a scene file (`b`, as read), checked: its geometry (meshes relative to `dir`),
/// spacing, placement in space, material, held and driven vertices, motion, inflation,
/// reference, landmarks; and its `place` under a landmark, if any, with where it stands in the
/// text, for [`resolve_places`] once every body is read (`earlier`: the bodies before it).
///
/// # Errors
/// [`Error::SceneFile`] naming the file, line and key of the first value that breaks a rule.
fn body_spec(
    src: Source<'_>,
    dir: &Path,
    units: Units,
    (k, b): (usize, RawBody),
    earlier: &[BodySpec],
) -> Result<(BodySpec, PlaceAt), Error> {
    let (file, text) = (src.file, src.text);
    let err = |span: Range<usize>, message: String| src.err(span, message);
    let key = |what: &str| format!("body[{k}].{what}");
    let name_span = b.name.span();
    let name = b.name.into_inner();
    if name.is_empty() {
        return Err(at(file, text, name_span, Some(&key("name")), "a body needs a name"));
    }
    if let Some(first) = earlier.iter().position(|o| o.name == name) {
        return Err(at(
            file,
            text,
            name_span,
            Some(&key("name")),
            format!("{name:?} is already the name of body[{first}]; names are unique"),
        ));
    }
    let b_kind = b.kind;
    let b_kind_is_soft = |k: BodyKind| k == BodyKind::Soft;
    let geometry = match (b.mesh, b.shape) {
        (Some(mesh), None) => Geometry::Mesh(dir.join(mesh.into_inner())),
        (None, Some(shape)) => {
            let span = shape.span();
            let mut shape = shape.into_inner();
            check_shape(&shape).map_err(|(k, m)| at(file, text, span.clone(), Some(&key(k)), m))?;
            if let Shape::Between(b) = &mut shape {
                if b_kind_is_soft(b_kind) {
                    b.outer = dir.join(&b.outer);
                    b.inner = dir.join(&b.inner);
                } else {
                    return Err(at(
                        file,
                        text,
                        span,
                        Some(&key("shape.between")),
                        format!("`between` makes a soft body's tissue; {name:?} is {b_kind:?}"),
                    ));
                }
            }
            Geometry::Shape(shape)
        }
        (Some(mesh), Some(_)) => {
            return Err(err(mesh.span(), format!("body {name:?} has both `mesh` and `shape`; give one")));
        }
        (None, None) => {
            return Err(at(
                file,
                text,
                name_span,
                Some(&format!("body[{k}]")),
                format!("body {name:?} needs `mesh` (a file) or `shape` (a built-in shape)"),
            ));
        }
    };
    let spacing = match b.spacing {
        Some(s) if !(s.get_ref().is_finite() && *s.get_ref() > 0.0) => {
            return Err(err(s.span(), format!("{} must be a positive length", s.get_ref())));
        }
        s => s.map(Spanned::into_inner),
    };
    let needs_spacing = match (&geometry, b.kind) {
        (_, BodyKind::Soft) => true,
        (Geometry::Shape(_), BodyKind::Shell | BodyKind::Rigid) => true,
        (Geometry::Mesh(_), _) => false,
    };
    if needs_spacing && spacing.is_none() {
        let what = if b.kind == BodyKind::Soft { "the lattice spacing" } else { "the surface edge length" };
        return Err(at(
            file,
            text,
            name_span,
            Some(&key("spacing")),
            format!("body {name:?} ({:?}) needs `spacing`, {what}", b.kind),
        ));
    }
    let scale_span = b.scale.span();
    let scale = b.scale.into_inner();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(err(scale_span, format!("{scale} must be positive")));
    }
    // A body between two surfaces lies where they do, in the file's axes.
    if matches!(geometry, Geometry::Shape(Shape::Between(_)))
        && (b.position != [0.0; 3] || b.rotation != [0.0; 3] || scale != 1.0)
    {
        let moved = if b.position != [0.0; 3] {
            "position"
        } else if b.rotation != [0.0; 3] {
            "rotation"
        } else {
            "scale"
        };
        return Err(at(
            file,
            text,
            name_span,
            Some(&key(moved)),
            format!(
                "body {name:?} lies between its surfaces, where they are: `{moved}` does not apply to `between` (move the surfaces and the box instead)"
            ),
        ));
    }
    if !b.position.iter().chain(&b.rotation).all(|v| v.is_finite()) {
        return Err(at(
            file,
            text,
            name_span,
            Some(&key("position")),
            "position and rotation must be finite",
        ));
    }
    let material_span = b.material.span();
    // (A default's span is empty at the file's start: no `material` was written.)
    let material_given = material_span != (0..0);
    let material = b.material.into_inner();
    check_material(&material).map_err(|(what, m)| {
        at(file, text, material_span.clone(), Some(&key(&format!("material.{what}"))), m)
    })?;
    let rules = |list: Vec<Spanned<Fixed>>| -> Result<Vec<Fixed>, Error> {
        let mut out = Vec::with_capacity(list.len());
        for f in list {
            let span = f.span();
            let f = f.into_inner();
            check_fixed(&f).map_err(|m| err(span.clone(), m))?;
            out.push(f);
        }
        Ok(out)
    };
    let fixed = rules(b.fixed)?;
    let driven = rules(b.driven)?;
    let mut layers = Vec::with_capacity(b.layers.len());
    for l in b.layers {
        let span = l.span();
        let l = l.into_inner();
        if b.kind != BodyKind::Soft {
            return Err(err(span, format!("only a soft body has layers; {name:?} is {:?}", b.kind)));
        }
        check_fixed(&l.region).map_err(|m| err(span.clone(), m))?;
        if !(l.young_kpa.is_finite() && l.young_kpa > 0.0) {
            return Err(err(span, format!("young_kpa = {} must be a positive modulus in kPa", l.young_kpa)));
        }
        layers.push(l);
    }
    if let Some(f) = b.floor
        && !f.is_finite()
    {
        return Err(at(file, text, name_span, Some(&key("floor")), "must be finite"));
    }
    let motion_span = b.motion.span();
    let motion = b.motion.into_inner();
    let moves = b.kind == BodyKind::Rigid || (b.kind == BodyKind::Soft && !driven.is_empty());
    if !motion.is_empty() && !moves {
        return Err(err(
            motion_span,
            format!(
                "only a rigid body, or a soft body with `driven` vertices, has `motion`; {name:?} is {:?}",
                b.kind
            ),
        ));
    }
    if motion
        .iter()
        .any(|m| !(m.t.is_finite() && m.position.iter().chain(&m.rotation).all(|v| v.is_finite())))
    {
        return Err(err(motion_span, "keyframes must be finite".into()));
    }
    if motion.windows(2).any(|w| w[1].t <= w[0].t) {
        return Err(err(motion_span, "keyframe times must increase".into()));
    }
    let inflate = inflate_of(src, (&name, b.kind), units, b.inflate)?;
    let reference = match b.reference {
        None => None,
        Some(r) => {
            let span = r.span();
            let g = r.into_inner().gravity;
            if !g.iter().all(|v| v.is_finite()) {
                return Err(err(span, "reference.gravity must be finite, in m/s²".into()));
            }
            if b.kind != BodyKind::Soft {
                return Err(err(
                    span,
                    format!(
                        "only a soft body's shape is recovered from a loaded one; {name:?} is {:?}",
                        b.kind
                    ),
                ));
            }
            Some(g)
        }
    };
    let place = place_of(src, (&name, b.kind), b.position != [0.0; 3] || b.rotation != [0.0; 3], b.place)?;
    let landmarks = landmarks_of(src, (&name, b.kind), b.landmarks)?;
    let material = if place.is_some() && !material_given { PLACED_SHELL_MATERIAL } else { material };
    let spec = BodySpec {
        place: None,
        reference,
        landmarks,
        name,
        kind: b.kind,
        geometry,
        spacing,
        position: b.position,
        rotation: b.rotation,
        scale,
        material,
        fixed,
        driven,
        layers,
        floor: b.floor,
        motion,
        inflate,
        flatten: None,
        sink: 0.0,
    };
    Ok((spec, place))
}

/// A body's `inflate` (`name`, of `kind`), checked: only a shell inflates, by a pressure, a
/// volume (in physical `units`) or a schedule of volumes, one of them.
///
/// # Errors
/// [`Error::SceneFile`] naming the file and line of the rule broken.
fn inflate_of(
    src: Source<'_>,
    (name, kind): (&str, BodyKind),
    units: Units,
    inflate: Option<Spanned<Inflate>>,
) -> Result<Option<Inflate>, Error> {
    Ok(match inflate {
        None => None,
        Some(i) => {
            let span = i.span();
            let i = i.into_inner();
            if kind != BodyKind::Shell {
                return Err(src.err(span, format!("only a shell inflates; {name:?} is {:?}", kind)));
            }
            let mut i = i;
            if let Some(&[_, last]) = i.schedule.last() {
                if i.pressure_kpa.is_some() || i.volume_ml.is_some() {
                    return Err(
                        src.err(span, "give `pressure_kpa`, `volume_ml` or `schedule`, one of them".into())
                    );
                }
                let finite = i.schedule.iter().flatten().all(|v| v.is_finite());
                let rising = i.schedule.windows(2).all(|w| w[1][0] > w[0][0] && w[1][1] >= w[0][1]);
                let positive = i.schedule.iter().all(|[_, ml]| *ml > 0.0);
                if !(finite && i.schedule[0][0] > 0.0 && rising && positive) {
                    return Err(src.err(
                        span,
                        "a `schedule` is [[t, volume_ml], …] with finite times that increase from above 0 and positive volumes that do not decrease".into(),
                    ));
                }
                i.volume_ml = Some(last);
                i.ramp = 0.0;
            }
            if i.volume_ml.is_some() && !units.is_physical() {
                return Err(src.err(
                    span,
                    "a scene in layer units has no millilitres: inflate it by `pressure_kpa`, or give the scene physical units (\"mm\", \"cm\" or \"m\")".into(),
                ));
            }
            let amount = match (i.pressure_kpa, i.volume_ml) {
                (Some(p), None) => p,
                (None, Some(v)) => v,
                _ => {
                    return Err(
                        src.err(span, "give `pressure_kpa`, `volume_ml` or `schedule`, one of them".into())
                    );
                }
            };
            if !(amount.is_finite() && amount >= 0.0 && i.ramp.is_finite() && i.ramp >= 0.0) {
                return Err(
                    src.err(span, "the inflation and its ramp must be finite and not negative".into())
                );
            }
            Some(i)
        }
    })
}

/// A body's `place` (`name`, of `kind`), checked where it can be before the other bodies are
/// read ([`resolve_places`] does the rest): only a shell is placed, and with no position or
/// rotation of its own (`positioned`: it has either).
///
/// # Errors
/// [`Error::SceneFile`] naming the file and line of the rule broken.
fn place_of(
    src: Source<'_>,
    (name, kind): (&str, BodyKind),
    positioned: bool,
    place: Option<Spanned<RawPlace>>,
) -> Result<PlaceAt, Error> {
    Ok(match place {
        None => None,
        Some(p) => {
            let span = p.span();
            let p = p.into_inner();
            if kind != BodyKind::Shell {
                return Err(src.err(
                    span,
                    format!("only a shell (an implant) is placed on a chest wall; {name:?} is {:?}", kind),
                ));
            }
            if positioned {
                return Err(src.err(
                    span,
                    format!(
                        "body {name:?} is placed under a landmark: its `position` and `rotation` follow from the chest wall, give neither"
                    ),
                ));
            }
            if let Some(m) = p.margin
                && !(m.is_finite() && m >= 0.0)
            {
                return Err(src.err(span, format!("place.margin = {m} must be 0 or more (file units)")));
            }
            if let Some(m) = p.friction
                && !(m.is_finite() && m >= 0.0)
            {
                return Err(src.err(
                    span,
                    format!("place.friction = {m} must be 0 (the implant slides freely) or more (Coulomb's coefficient)"),
                ));
            }
            Some((span, p))
        }
    })
}

/// A body's `landmarks` (`name`, of `kind`), checked: only a soft body has them, each a
/// finite point.
///
/// # Errors
/// [`Error::SceneFile`] naming the file and line of the rule broken.
fn landmarks_of(
    src: Source<'_>,
    (name, kind): (&str, BodyKind),
    landmarks: Option<Spanned<std::collections::BTreeMap<String, [f64; 3]>>>,
) -> Result<Vec<(String, [f64; 3])>, Error> {
    Ok(match landmarks {
        None => Vec::new(),
        Some(l) => {
            let span = l.span();
            let l = l.into_inner();
            if kind != BodyKind::Soft {
                return Err(src.err(span, format!("only a soft body has landmarks; {name:?} is {:?}", kind)));
            }
            if let Some((n, _)) = l.iter().find(|(_, p)| !p.iter().all(|v| v.is_finite())) {
                return Err(src.err(span, format!("landmark {n:?} must be a finite point [x, y, z]")));
            }
            l.into_iter().collect()
        }
    })
}

/// Each body's `place = { under = "body.landmark" }` (`places`, by body, with where each
/// stands in the text) resolved against `bodies`: the body named has a chest wall and the
/// landmark, and the margin defaults to the pocket's.
///
/// # Errors
/// [`Error::SceneFile`] naming the file and line of a placement that names no such body or
/// landmark, or a body without a chest wall.
fn resolve_places(
    src: Source<'_>,
    units: Units,
    bodies: &mut [BodySpec],
    places: Vec<PlaceAt>,
) -> Result<(), Error> {
    for (k, place) in places.into_iter().enumerate() {
        let Some((span, p)) = place else { continue };
        let Some((body, landmark)) = p.under.split_once('.') else {
            return Err(src.err(
                span,
                format!("place.under = {:?} must name a body and its landmark: \"breast.nipple\"", p.under),
            ));
        };
        let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
        let Some(t) = bodies.iter().position(|b| b.name == body) else {
            return Err(
                src.err(span, format!("place.under: no body is named {body:?} (the bodies: {names:?})"))
            );
        };
        if !matches!(bodies[t].geometry, Geometry::Shape(Shape::Between(_))) {
            return Err(src.err(
                span,
                format!(
                    "place.under: body {body:?} has no chest wall: an implant is placed on a body with shape = {{ between = {{ outer, inner, min, max }} }}"
                ),
            ));
        }
        let marks: Vec<&str> = bodies[t].landmarks.iter().map(|(n, _)| n.as_str()).collect();
        if !marks.contains(&landmark) {
            return Err(src.err(
                span,
                format!("place.under: body {body:?} has no landmark {landmark:?} (its landmarks: {marks:?})"),
            ));
        }
        let mut within = Vec::new();
        for border in p.within.iter().flatten() {
            let mark = match border.split_once('.') {
                Some((b, m)) if b == body => m,
                _ => {
                    return Err(src.err(
                        span,
                        format!(
                            "place.within: {border:?} must name a landmark of {body:?}, the body it stands on: \"{body}.medial\""
                        ),
                    ));
                }
            };
            if !marks.contains(&mark) {
                return Err(src.err(
                    span,
                    format!(
                        "place.within: body {body:?} has no landmark {mark:?} (its landmarks: {marks:?})"
                    ),
                ));
            }
            if mark == landmark {
                return Err(src.err(
                    span,
                    format!(
                        "place.within: {border:?} is the landmark the implant stands under, not a border"
                    ),
                ));
            }
            within.push(mark.to_string());
        }
        let margin = p.margin.unwrap_or(POCKET_MARGIN_MM * 1e-3 / units.metres());
        let friction = p.friction.unwrap_or(SMOOTH_SHELL_FRICTION);
        bodies[k].place = Some(Placement {
            body: t,
            landmark: landmark.to_string(),
            within,
            margin,
            friction,
            contact_added: false,
        });
    }
    Ok(())
}

/// For each shell placed on a patient (`place`) that no contact pairs with her tissue, in
/// either order, the default contact between them: `a` the implant (binned, as a contact's
/// indexed body is), `b` the tissue, every other key its default. [`Placement::contact_added`]
/// says so, and `run` prints it. docs/design.md §15's example writes no `[[contact]]`, and an
/// implant with nothing to stop it passes through the tissue it fills under.
fn add_placed_contacts(bodies: &mut [BodySpec], contacts: &mut Vec<ContactSpec>) {
    for (k, body) in bodies.iter_mut().enumerate() {
        let Some(place) = body.place.as_mut() else { continue };
        let t = place.body;
        if contacts.iter().any(|c| (c.a, c.b) == (k, t) || (c.a, c.b) == (t, k)) {
            continue;
        }
        contacts.push(ContactSpec {
            a: k,
            b: t,
            direction: DirectionSpec::default(),
            search: SearchSpec::default(),
            radius: Auto::default(),
            voxel_size: Auto::default(),
            magnitude: Auto::default(),
            response: ResponseSpec::default(),
            stiffness: Auto::default(),
            gap: Auto::default(),
        });
        place.contact_added = true;
    }
}

/// A `[[contact]]` of a scene file (`c`, as read), checked against its `bodies`: two
/// different bodies by name, positive sizes, a voxel size that is a power of two, and no
/// penalty's keys on the paper's constant response.
///
/// # Errors
/// [`Error::SceneFile`] naming the file and line of the first value that breaks a rule.
fn contact_spec(src: Source<'_>, bodies: &[BodySpec], c: RawContact) -> Result<ContactSpec, Error> {
    let find = |s: &Spanned<String>| {
        bodies.iter().position(|b| b.name == *s.get_ref()).ok_or_else(|| {
            let names: Vec<&str> = bodies.iter().map(|b| b.name.as_str()).collect();
            src.err(s.span(), format!("no body is named {:?} (the bodies: {names:?})", s.get_ref()))
        })
    };
    let (a, b) = (find(&c.a)?, find(&c.b)?);
    if a == b {
        return Err(src.err(c.b.span(), "a contact needs two different bodies".into()));
    }
    for (what, v) in [
        ("radius", &c.radius),
        ("voxel_size", &c.voxel_size),
        ("magnitude", &c.magnitude),
        ("stiffness", &c.stiffness),
    ] {
        if let Auto::Value(x) = v.get_ref()
            && !(x.is_finite() && *x > 0.0)
        {
            return Err(src.err(v.span(), format!("{what} {x} must be \"auto\" or positive")));
        }
    }
    if let Auto::Value(v) = c.voxel_size.get_ref()
        && frexp(*v).0 != 0.5
    {
        return Err(src.err(c.voxel_size.span(), format!("{v} is not a power of two")));
    }
    if let Auto::Value(g) = c.gap.get_ref()
        && !(g.is_finite() && *g >= 0.0)
    {
        return Err(src.err(c.gap.span(), format!("gap {g} must be \"auto\" or 0 or more")));
    }
    if c.response == ResponseSpec::Constant {
        for (what, v) in [("stiffness", &c.stiffness), ("gap", &c.gap)] {
            if matches!(v.get_ref(), Auto::Value(_)) {
                return Err(src.err(
                    v.span(),
                    format!("{what} is a penalty's; response = \"constant\" pushes with the magnitude alone"),
                ));
            }
        }
    }
    Ok(ContactSpec {
        a,
        b,
        direction: c.direction,
        search: c.search,
        radius: *c.radius.get_ref(),
        voxel_size: *c.voxel_size.get_ref(),
        magnitude: *c.magnitude.get_ref(),
        response: c.response,
        stiffness: *c.stiffness.get_ref(),
        gap: *c.gap.get_ref(),
    })
}

/// The file's error at `span`.
pub(crate) fn at(
    file: &str,
    text: &str,
    span: Range<usize>,
    key: Option<&str>,
    message: impl Into<String>,
) -> Error {
    let (line, column) = line_column(text, span.start);
    Error::SceneFile {
        file: file.to_string(),
        line,
        column,
        key: key.map_or_else(|| key_at(text, span.start), str::to_string),
        message: message.into(),
    }
}

/// The text of `path` (`what` it is, for the message), or its error at line 0.
pub(crate) fn read_text(path: &Path, what: &str) -> Result<String, Error> {
    std::fs::read_to_string(path).map_err(|e| Error::SceneFile {
        file: path.display().to_string(),
        line: 0,
        column: 0,
        key: String::new(),
        message: format!("cannot read {what}: {e}"),
    })
}

/// A TOML syntax or type error of `file` as [`Error::SceneFile`]: its line, column and key (an
/// unknown key's span is the key itself, named by its table's path).
pub(crate) fn toml_error(file: &str, text: &str, e: &toml::de::Error) -> Error {
    let span = e.span().unwrap_or(0..0);
    let message = e.message().trim().to_string();
    let key = message.strip_prefix("unknown field `").and_then(|m| m.split('`').next()).map(|unknown| {
        let context = key_at(text, span.start);
        if context.ends_with(unknown) {
            context
        } else if context.is_empty() {
            unknown.to_string()
        } else {
            format!("{context}.{unknown}")
        }
    });
    at(file, text, span, key.as_deref(), message)
}

/// The error for the first of the `[[table]]`s' geometries (in order) whose mesh is not a
/// file, pointing at its `mesh` key.
pub(crate) fn missing_mesh<'a>(
    file: &str,
    text: &str,
    table: &str,
    geometries: impl Iterator<Item = &'a Geometry>,
) -> Result<(), Error> {
    for (k, geometry) in geometries.enumerate() {
        if let Geometry::Shape(Shape::Between(b)) = geometry {
            for (key, path) in [("outer", &b.outer), ("inner", &b.inner)] {
                if !path.is_file() {
                    let offset = nth_table(text, table, k)
                        .and_then(|t| text[t..].find(key).map(|i| t + i))
                        .unwrap_or(0);
                    return Err(at(
                        file,
                        text,
                        offset..offset,
                        Some(&format!("{table}[{k}].shape.between.{key}")),
                        format!("{} does not exist or is not a file", path.display()),
                    ));
                }
            }
        }
        if let Geometry::Mesh(mesh) = geometry
            && !mesh.is_file()
        {
            let offset =
                nth_table(text, table, k).and_then(|t| text[t..].find("mesh").map(|i| t + i)).unwrap_or(0);
            return Err(at(
                file,
                text,
                offset..offset,
                Some(&format!("{table}[{k}].mesh")),
                format!("{} does not exist or is not a file", mesh.display()),
            ));
        }
    }
    Ok(())
}

impl SceneFile {
    /// Reads and checks the scene file at `path`; meshes are resolved against its folder and
    /// must exist.
    ///
    /// # Errors
    /// [`Error::SceneFile`] naming the file, line, column and key for anything the file gets
    /// wrong, or, at line 0, for a file that cannot be read.
    pub fn read(path: impl AsRef<Path>) -> Result<SceneFile, Error> {
        let path = path.as_ref();
        let text = read_text(path, "the scene file")?;
        let scene = SceneFile::parse(path, &text)?;
        let meshes = scene.bodies.iter().map(|b| &b.geometry);
        missing_mesh(&path.display().to_string(), &text, "body", meshes)?;
        Ok(scene)
    }

    /// Parses and checks scene `text` as if read from `path` (mesh paths are resolved against
    /// its folder, and not looked for).
    ///
    /// # Errors
    /// As [`read`](Self::read), but for the mesh files.
    pub fn parse(path: impl AsRef<Path>, text: &str) -> Result<SceneFile, Error> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let raw: RawScene = toml::from_str(text).map_err(|e| toml_error(&file, text, &e))?;
        let dir = path.parent().unwrap_or(Path::new(""));

        let mut time = raw.time;
        let time_err = |key: &str, message: String| {
            let offset = find_key(text, "time", key);
            at(&file, text, offset..offset, Some(&format!("time.{key}")), message)
        };
        if time.duration.is_some() && time.steps.is_some() {
            return Err(time_err("steps", "give `duration` or `steps`, not both".into()));
        }
        if let Some(d) = time.duration
            && !(d.is_finite() && d > 0.0)
        {
            return Err(time_err("duration", format!("{d} must be positive seconds")));
        }
        if time.steps == Some(0) {
            return Err(time_err("steps", "at least 1".into()));
        }
        if time.max_steps == 0 {
            return Err(time_err("max_steps", "at least 1".into()));
        }
        if let Auto::Value(dt) = time.dt
            && !(dt.is_finite() && dt > 0.0)
        {
            return Err(time_err("dt", format!("{dt} must be \"auto\" or positive seconds")));
        }
        if time.duration.is_none() && time.steps.is_none() {
            time.duration = Some(1.0);
        }

        let mut bodies: Vec<BodySpec> = Vec::with_capacity(raw.body.len());
        let mut places = Vec::with_capacity(bodies.capacity());
        for (k, b) in raw.body.into_iter().enumerate() {
            let (spec, place) = body_spec(Source { file: &file, text }, dir, raw.units, (k, b), &bodies)?;
            bodies.push(spec);
            places.push(place);
        }

        // Placements name a body and its landmark: resolved once every body is read.
        resolve_places(Source { file: &file, text }, raw.units, &mut bodies, places)?;

        let mut contacts = raw
            .contact
            .into_iter()
            .map(|c| contact_spec(Source { file: &file, text }, &bodies, c))
            .collect::<Result<Vec<_>, Error>>()?;
        add_placed_contacts(&mut bodies, &mut contacts);
        let world_span = raw.world.span();
        let world = raw.world.into_inner();
        if let Some(g) = world.gravity
            && !g.iter().all(|v| v.is_finite())
        {
            let offset = find_key(text, "world", "gravity");
            let offset = if offset == 0 { world_span.start } else { offset };
            return Err(at(&file, text, offset..offset, Some("world.gravity"), "must be finite, in m/s²"));
        }
        if raw.output.frames == 0 {
            let offset = find_key(text, "output", "frames");
            return Err(at(&file, text, offset..offset, Some("output.frames"), "at least 1 frame"));
        }
        // A scene in physical units that names no integrator gets the implicit one, which comes
        // to rest where the explicit one, bound to its short stable step, may not (a shipped
        // comparison's candidate was not at rest after 30,000 explicit steps). The paper's layer
        // units keep its explicit one, and so do the voxel model's responses, which hold only
        // under it (docs/integrator.md).
        if raw.units.is_physical()
            && contacts.iter().all(|c| c.response == ResponseSpec::Surface)
            && !names_integrator(text)
        {
            time.integrator = IntegratorSpec::Implicit;
        }
        Ok(SceneFile {
            path: path.to_path_buf(),
            units: raw.units,
            time,
            world,
            bodies,
            contacts,
            output: raw.output,
            text: text.to_string(),
        })
    }

    /// An [`Error::SceneFile`] about `key` (a key of the `k`-th `[[body]]`, or a path below one
    /// such as `inflate.volume_ml`) found after parsing, when the world is built: at the line
    /// and column where the body writes that key (its first part), or where the body's table
    /// starts when it does not.
    #[must_use]
    pub fn body_error(&self, k: usize, key: &str, message: impl Into<String>) -> Error {
        let top = key.split('.').next().unwrap_or(key);
        let offset = nth_table(&self.text, "body", k).map_or(0, |start| {
            let mut offset = start;
            for line in self.text[start..].split_inclusive('\n') {
                let t = line.trim_start();
                if t.starts_with('[') && offset > start {
                    break;
                }
                if t.split_once('=').is_some_and(|(name, _)| name.trim() == top) {
                    return offset + (line.len() - t.len());
                }
                offset += line.len();
            }
            start
        });
        let (line, column) = line_column(&self.text, offset);
        Error::SceneFile {
            file: self.path.display().to_string(),
            line,
            column,
            key: format!("body[{k}].{key}"),
            message: message.into(),
        }
    }

    /// Metres per file unit.
    #[must_use]
    pub fn metres(&self) -> f64 {
        self.units.metres()
    }
}

/// `x = m · 2^e` with `m` in `[0.5, 1)` (0 for 0).
fn frexp(x: f64) -> (f64, i32) {
    if x == 0.0 || !x.is_finite() {
        return (0.0, 0);
    }
    let e = x.abs().log2().floor() as i32 + 1;
    (x / 2f64.powi(e), e)
}

/// The byte offset of `key = ` under the `[table]` header: the key's first character, or the
/// header's when the key is not written there (0 when there is no such table).
/// Whether the file's `[time]` names an integrator (the text is already known to parse).
fn names_integrator(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).ok().is_some_and(|t| {
        t.get("time").and_then(toml::Value::as_table).is_some_and(|t| t.contains_key("integrator"))
    })
}

fn find_key(text: &str, table: &str, key: &str) -> usize {
    let header = format!("[{table}]");
    let mut offset = 0;
    let mut inside = None;
    for line in text.split_inclusive('\n') {
        let t = line.trim_start();
        let indent = line.len() - t.len();
        if t.starts_with('[') {
            if inside.is_some() {
                break;
            }
            if t.trim_end().starts_with(&header) {
                inside = Some(offset + indent);
            }
        } else if inside.is_some() && t.split_once('=').is_some_and(|(k, _)| k.trim() == key) {
            return offset + indent;
        }
        offset += line.len();
    }
    inside.unwrap_or(0)
}

/// The byte offset where the `k`-th `[[name]]` table starts.
pub(crate) fn nth_table(text: &str, name: &str, k: usize) -> Option<usize> {
    let header = format!("[[{name}]]");
    let mut from = 0;
    for _ in 0..=k {
        let i = text[from..].find(&header)? + from;
        from = i + header.len();
    }
    Some(from)
}

/// A shape's sizes: positive, and an implant's volume one that its base and projection hold.
/// The error's key below `body[k]`, and its message.
pub(crate) fn check_shape(shape: &Shape) -> Result<(), (&'static str, String)> {
    let positive = |v: &[f64]| v.iter().all(|x| x.is_finite() && *x > 0.0);
    let ok = match shape {
        Shape::Box(s) | Shape::Ellipsoid(s) => positive(s),
        Shape::Sphere(r) => positive(&[*r]),
        Shape::Cylinder { radius, height } => positive(&[*radius, *height]),
        Shape::Between(b) => {
            let finite = b.min.iter().chain(&b.max).all(|v| v.is_finite());
            if !(finite && (0..3).all(|k| b.max[k] > b.min[k])) {
                return Err((
                    "shape.between.max",
                    format!("the box {:?}..{:?} must be finite, each of max above min", b.min, b.max),
                ));
            }
            true
        }
        Shape::Implant { volume_ml, base_mm, projection_mm, .. } => {
            if positive(&[*volume_ml, *base_mm, *projection_mm]) {
                // The catalogue's units, mL (1000 mm³) and mm, whatever the file's.
                let dome = crate::bodies::ImplantShape {
                    volume: 1e3 * volume_ml,
                    base: *base_mm,
                    projection: *projection_mm,
                    anatomical: false,
                };
                if dome.exponent().is_err() {
                    let cylinder_ml = std::f64::consts::PI * (0.5 * base_mm).powi(2) * projection_mm / 1e3;
                    let least = cylinder_ml / (crate::bodies::MAX_IMPLANT_EXPONENT + 1.0);
                    return Err((
                        "shape.implant.volume_ml",
                        format!(
                            "an implant of base {base_mm} mm and projection {projection_mm} mm holds more than {least:.1} mL and less than {cylinder_ml:.1} mL (its cylinder)"
                        ),
                    ));
                }
            }
            positive(&[*volume_ml, *base_mm, *projection_mm])
        }
    };
    if ok { Ok(()) } else { Err(("shape", format!("{shape:?}: every size must be positive"))) }
}

fn check_material(m: &MaterialSpec) -> Result<(), (&'static str, String)> {
    if !(m.young_kpa.is_finite() && m.young_kpa > 0.0) {
        return Err(("young_kpa", format!("{} must be a positive modulus in kPa", m.young_kpa)));
    }
    if !(m.poisson.is_finite() && (0.0..0.5).contains(&m.poisson)) {
        return Err(("poisson", format!("{} must be in [0, 0.5)", m.poisson)));
    }
    if !(m.density.is_finite() && m.density > 0.0) {
        return Err(("density", format!("{} must be a positive density in kg/m³", m.density)));
    }
    if !(m.damping.is_finite() && m.damping >= 0.0) {
        return Err(("damping", format!("{} must be finite and not negative", m.damping)));
    }
    if let Some(d) = m.spring_damping
        && !(d.is_finite() && d >= 0.0)
    {
        return Err(("spring_damping", format!("{d} must be finite and not negative")));
    }
    Ok(())
}

fn check_fixed(f: &Fixed) -> Result<(), String> {
    match f {
        Fixed::Below(a) | Fixed::Above(a) => match a.get() {
            Some((_, v)) if v.is_finite() => Ok(()),
            Some(_) => Err("the plane's coordinate must be finite".into()),
            None => Err("give exactly one of x, y, z".into()),
        },
        Fixed::InsideBox { min, max } => {
            if min.iter().chain(max).all(|v| v.is_finite()) && (0..3).all(|k| min[k] <= max[k]) {
                Ok(())
            } else {
                Err(format!("the box {min:?}..{max:?} must be finite with min <= max"))
            }
        }
        Fixed::Rim(w) => {
            if w.is_finite() && *w >= 0.0 {
                Ok(())
            } else {
                Err(format!("rim width {w} must be finite and not negative"))
            }
        }
        Fixed::Depth(d) => {
            if d.is_finite() && *d > 0.0 {
                Ok(())
            } else {
                Err(format!("depth {d} must be a positive length"))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_column_and_key_point_at_the_offset() {
        let text =
            "units = \"mm\"\n[[body]]\nname = \"a\"\n[[body]]\nname = \"b\"\nmaterial = { poisson = 0.7 }\n";
        let at = text.find("0.7").unwrap();
        assert_eq!(line_column(text, at), (6, 24));
        assert_eq!(key_at(text, at), "body[1].material.poisson");
        assert_eq!(key_at(text, text.find("\"a\"").unwrap()), "body[0].name");
        assert_eq!(key_at(text, 0), "units");
    }

    #[test]
    fn powers_of_two() {
        assert_eq!(frexp(1.0).0, 0.5);
        assert_eq!(frexp(0.25).0, 0.5);
        assert_ne!(frexp(0.3).0, 0.5);
    }
}
