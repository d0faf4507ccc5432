//! The object options shared by `modalforge modes` and `modalforge render`: shape, material,
//! size and resolution, element, solver, strike (the `modes` report they lead to: `object/report.rs`).

use modalforge::basis::{BasisError, Hit, ModeBasis};
use modalforge::eigen::{EigenOptions, ModeCount, SolverKind};
use modalforge::fem::ElementKind;
use modalforge::material::{DampingLaw, Material, MaterialError};
use modalforge::shape::mesh::{self, MeshError};
use modalforge::shape::spec::{self, ShapeSpec, SpecError};
use modalforge::shape::vox::{self, VoxError};
use modalforge::shape::VoxelGrid;
mod report;

pub use report::{neural_report, report, ModesReport};

/// The shape without `--shape`: the demo bar's (`render` also gives it the demo bar's length).
pub const DEFAULT_SHAPE: &str = "bar:64x4x4";

/// Default largest extent of an object when neither `--size` nor `--voxel-size` is given.
pub const DEFAULT_SIZE_M: f64 = 0.2;

/// Object options.
#[derive(clap::Args, Debug, Clone)]
pub struct ObjectArgs {
    /// Shape: a built-in with parameters in voxels, such as `bowl:d=32,wall=2` or `bar:64x4x4`
    /// (the README lists them; a wrong name lists the names), or a .vox, .obj or .stl file.
    #[arg(long, value_name = "SPEC")]
    pub shape: Option<String>,
    /// Material: a preset (`modalforge materials` lists them), a .toml file, or
    /// E,RHO,NU[,ALPHA1,ALPHA2] in SI units.
    #[arg(
        long,
        value_name = "NAME",
        default_value = "steel",
        allow_hyphen_values = true
    )]
    pub material: String,
    /// Damping model of the preset [default: the preset's own].
    #[arg(long, value_name = "MODEL", value_enum)]
    pub damping: Option<DampingLaw>,
    /// Voxel edge length in metres (fixes the size and the resolution).
    #[arg(
        long,
        value_name = "M",
        conflicts_with = "size",
        allow_negative_numbers = true
    )]
    pub voxel_size: Option<f64>,
    /// Largest extent of the object in metres [default: 0.2].
    #[arg(long, value_name = "M", allow_negative_numbers = true)]
    pub size: Option<f64>,
    /// Voxels along the longest side: a number, or `auto` to pick it from --size and --fmax
    /// [default: the shape's own; auto for meshes].
    #[arg(long, value_name = "N|auto")]
    pub resolution: Option<String>,
    /// Split every voxel into N x N x N smaller ones: the same staircased object on a finer
    /// mesh (a convergence check; costs about N^3 more).
    #[arg(long, value_name = "N", default_value_t = 1,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=8))]
    pub split: usize,
    /// Rasterise built-in shapes as a binary staircase (a voxel solid when its centre is
    /// inside) instead of keeping how full the voxels the surface cuts are.
    #[arg(long)]
    pub staircase: bool,
    /// Finite element.
    #[arg(long, value_name = "NAME", value_enum, default_value_t = ElementKind::Hex8Incompatible)]
    pub element: ElementKind,
    /// Eigensolver, or the neural predictor.
    #[arg(long, value_name = "NAME", value_enum, default_value_t = SolverChoice::Fem(SolverKind::Auto))]
    pub solver: SolverChoice,
    /// Weights for --solver neural (a `modalforge train` checkpoint's model.bpk) [default: the
    /// shipped ones].
    #[arg(long, value_name = "FILE.bpk")]
    pub weights: Option<std::path::PathBuf>,
    /// Residual tolerance of the eigensolver (NeuralSound eq. 6); LOBPCG never stops above 1e-6.
    #[arg(long, value_name = "TOL", default_value_t = modalforge::eigen::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Strike point X,Y,Z in metres from the object's minimum corner (snapped to the nearest
    /// surface) [default: the top face, off-centre].
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub hit: Option<Vec<f64>>,
    /// Force direction DX,DY,DZ [default: into the struck face].
    #[arg(
        long,
        value_name = "DX,DY,DZ",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub force: Option<Vec<f64>>,
}

/// `--solver`: one of the FEM eigensolvers, or the neural predictor. Its names are
/// [`SolverKind`]'s own and `neural`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverChoice {
    /// Finite elements, solved by this eigensolver.
    Fem(SolverKind),
    /// The trained predictor: milliseconds, approximate; one mode per predicted band.
    Neural,
}

impl clap::ValueEnum for SolverChoice {
    fn value_variants<'a>() -> &'a [Self] {
        &[
            Self::Fem(SolverKind::Auto),
            Self::Fem(SolverKind::Lanczos),
            Self::Fem(SolverKind::Lobpcg),
            Self::Neural,
        ]
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        match self {
            Self::Fem(kind) => kind.to_possible_value(),
            Self::Neural => Some(clap::builder::PossibleValue::new("neural").help(
                "the trained predictor: milliseconds, approximate; one mode per predicted band",
            )),
        }
    }
}

impl std::fmt::Display for SolverChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        modalforge::cli_name(self, f)
    }
}

/// Why an object could not be built or solved.
#[derive(Debug, thiserror::Error)]
pub enum ObjectError {
    /// Bad shape spec.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// Bad .vox file.
    #[error(transparent)]
    Vox(#[from] VoxError),
    /// Bad mesh file.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// Bad material.
    #[error(transparent)]
    Material(#[from] MaterialError),
    /// Shape, solve or voicing failed.
    #[error(transparent)]
    Modal(#[from] BasisError),
    /// A bad option value.
    #[error("{0}")]
    Option(String),
    /// The neural predictor cannot answer.
    #[error(transparent)]
    Predictor(#[from] modalforge::predictor::PredictorError),
}

/// A shape ready to solve, with its physical scale.
pub struct Object {
    /// The voxels.
    pub grid: VoxelGrid,
    /// The material.
    pub material: Material,
    /// Element.
    pub element: ElementKind,
    /// Solver (FEM).
    pub solver: SolverKind,
    /// `--solver neural`: the predictor answers instead of FEM.
    pub neural: bool,
}

fn positive(name: &str, v: f64) -> Result<f64, ObjectError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ObjectError::Option(format!(
            "{name} {v} must be a positive finite number"
        )))
    }
}

/// Checks the values of an `X,Y,Z` option (clap splits them at the commas).
pub fn vec3(name: &str, v: &[f64]) -> Result<[f64; 3], ObjectError> {
    match v {
        &[x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => {
            let given: Vec<String> = v.iter().map(f64::to_string).collect();
            Err(ObjectError::Option(format!(
                "{name} '{}' must be three finite numbers X,Y,Z",
                given.join(",")
            )))
        }
    }
}

/// `--material`, with `--damping`'s law when given.
fn material_of(args: &ObjectArgs) -> Result<Material, ObjectError> {
    let material = Material::parse(&args.material)?;
    let Some(law) = args.damping else {
        return Ok(material);
    };
    material.clone().with_damping_law(law).ok_or_else(|| {
        let have: Vec<&str> = material
            .damping_models
            .iter()
            .map(|(n, _)| n.as_str())
            .collect();
        ObjectError::Option(format!(
            "material {} has no damping model '{law}' (it has {})",
            material.name,
            have.join(", ")
        ))
    })
}

/// What `--resolution` needs to pick a resolution.
struct Resolution<'a> {
    args: &'a ObjectArgs,
    material: &'a Material,
    element: ElementKind,
    size_m: f64,
    fmax_hz: Option<f64>,
}

impl Resolution<'_> {
    /// Voxels along the longest side for a shape whose thinnest feature is `thinnest` of its
    /// `longest` side: `--resolution N`, `auto` (from `--fmax`), or `None` for the shape's own.
    fn voxels(&self, longest: f64, thinnest: f64) -> Result<Option<usize>, ObjectError> {
        match self.args.resolution.as_deref() {
            None => Ok(None),
            Some("auto") => {
                let f = self
                    .fmax_hz
                    .ok_or_else(|| ObjectError::Option("--resolution auto needs --fmax".into()))?;
                Ok(Some(self.auto(thinnest / longest, f)))
            }
            Some(n) => match n.parse::<usize>() {
                Ok(r) if (1..=modalforge::shape::MAX_GRID_DIM).contains(&r) => Ok(Some(r)),
                _ => Err(ObjectError::Option(format!(
                    "--resolution {n} must be auto or a whole number from 1 to {}",
                    modalforge::shape::MAX_GRID_DIM
                ))),
            },
        }
    }

    fn auto(&self, thinnest_fraction: f64, fmax_hz: f64) -> usize {
        modalforge::fem::auto_resolution(
            self.material,
            self.element,
            self.size_m,
            thinnest_fraction,
            fmax_hz,
        )
    }
}

/// The voxels of a spec at the resolution asked for (scale: one voxel per unit until the
/// physical size is applied).
fn voxels_of(
    spec: &ShapeSpec,
    staircase: bool,
    resolution: &Resolution,
) -> Result<VoxelGrid, ObjectError> {
    Ok(match spec {
        ShapeSpec::Primitive { shape, hollow } => {
            let ext = shape.extent();
            let longest = ext.iter().copied().fold(0.0, f64::max);
            let scale = match resolution.voxels(longest, shape.thinnest())? {
                Some(r) => r as f64 / longest,
                None => 1.0,
            };
            if staircase {
                let grid = shape
                    .rasterize_staircase(scale, 1.0)
                    .map_err(BasisError::from)?;
                spec::hollowed(grid, *hollow, scale)
            } else {
                let block = resolution.element.voxels_per_element();
                spec::primitive_voxels(shape, *hollow, scale, block).map_err(BasisError::from)?
            }
        }
        ShapeSpec::Vox(path) => vox::read_vox(path, 1.0)?,
        ShapeSpec::Mesh(path) => {
            // A mesh's thinnest feature is unknown: assume a twentieth of its size; without
            // --fmax or --resolution it gets the predictor's and the editor's 32 voxels.
            const MESH_THINNEST: f64 = 0.05;
            const MESH_VOXELS: usize = 32;
            let m = mesh::read_mesh(path)?;
            let name = path.display().to_string();
            let r = match resolution.voxels(1.0, MESH_THINNEST)? {
                Some(r) => r,
                None => resolution
                    .fmax_hz
                    .map_or(MESH_VOXELS, |f| resolution.auto(MESH_THINNEST, f)),
            };
            mesh::voxelize(&m, r, &name)?
        }
    })
}

impl Object {
    /// Builds the object from the options; `fmax_hz` drives `--resolution auto`.
    pub fn from_args(args: &ObjectArgs, fmax_hz: Option<f64>) -> Result<Self, ObjectError> {
        let material = material_of(args)?;
        let element = args.element;
        let (solver, neural) = match args.solver {
            SolverChoice::Fem(kind) => (kind, false),
            SolverChoice::Neural => (SolverKind::Auto, true),
        };
        if let Some(v) = args.voxel_size {
            positive("--voxel-size", v)?;
        }
        let size_m = positive("--size", args.size.unwrap_or(DEFAULT_SIZE_M))?;
        let resolution = Resolution {
            args,
            material: &material,
            element,
            size_m,
            fmax_hz,
        };
        let spec: ShapeSpec = args.shape.as_deref().unwrap_or(DEFAULT_SHAPE).parse()?;
        let grid = voxels_of(&spec, args.staircase, &resolution)?;
        // Physical scale: --voxel-size, else --size over the grid's longest side.
        let longest_vox = *grid.dims().iter().max().unwrap() as f64;
        let h = args.voxel_size.unwrap_or(size_m / longest_vox);
        let grid = grid.with_voxel_size(h).map_err(BasisError::from)?;
        let grid = match args.split {
            1 => grid,
            n => grid.split(n).map_err(BasisError::from)?,
        };
        grid.check_solvable().map_err(BasisError::from)?;
        Ok(Object {
            grid,
            material,
            element,
            solver,
            neural,
        })
    }

    /// The predictor's answer (`--solver neural`), with the strike from `--hit` / `--force`
    /// (default: the FEM path's default hit point, pushing into the object).
    pub fn predict(
        &self,
        args: &ObjectArgs,
    ) -> Result<(modalforge::predictor::object::PredictedObject, Hit), ObjectError> {
        let predictor = match &args.weights {
            Some(path) => modalforge::predictor::Predictor::from_file(path),
            None => modalforge::predictor::Predictor::shipped(),
        }?;
        let longest = self.grid.dims().into_iter().max().unwrap_or(0);
        if modalforge::predictor::object::input_side(longest) != longest {
            eprintln!(
                "note: the shape ({:?} voxels) is resampled to fill the predictor's {}^3 box \
                 (it sees shapes {}-{} voxels long as they are)",
                self.grid.dims(),
                modalforge::predictor::bands::INPUT_SIDE,
                modalforge::predictor::object::MIN_UNSCALED_SIDE,
                modalforge::predictor::bands::INPUT_SIDE
            );
        }
        let predicted = predictor.predict(&self.grid)?;
        let h = self.grid.voxel_size_m();
        let [nx, ny, nz] = self.grid.dims();
        let mut hit = Hit {
            point_m: [0.37 * nx as f64 * h, 0.41 * ny as f64 * h, nz as f64 * h],
            direction: None,
        };
        if let Some(p) = &args.hit {
            hit.point_m = vec3("--hit", p)?;
        }
        if let Some(f) = &args.force {
            hit.direction = Some(vec3("--force", f)?);
        }
        Ok((predicted, hit))
    }

    /// Solves the shape for `count` modes.
    pub fn solve(&self, count: ModeCount, tolerance: f64) -> Result<ModeBasis, ObjectError> {
        let options = EigenOptions {
            count,
            tolerance,
            ..Default::default()
        };
        Ok(ModeBasis::solve(
            &self.grid,
            self.element,
            self.material.poisson_ratio,
            self.solver,
            &options,
        )?)
    }

    /// The mode count for `--modes K` / `--fmax HZ`, in reference units.
    pub fn count(
        &self,
        modes: Option<usize>,
        fmax_hz: Option<f64>,
    ) -> Result<ModeCount, ObjectError> {
        match (modes, fmax_hz) {
            (Some(k), _) => Ok(ModeCount::First(k)),
            (None, Some(f)) => Ok(ModeCount::Below(ModeBasis::reference_bound(
                &self.material,
                self.grid.voxel_size_m(),
                positive("--fmax", f)?,
            ))),
            (None, None) => Ok(ModeCount::First(20)),
        }
    }

    /// The strike from `--hit` / `--force` (default: [`Hit::default_for`] the object's grid).
    pub fn hit(&self, args: &ObjectArgs) -> Result<Hit, ObjectError> {
        let mut hit = Hit::default_for(self.grid.dims(), self.grid.voxel_size_m());
        if let Some(h) = &args.hit {
            hit.point_m = vec3("--hit", h)?;
        }
        if let Some(f) = &args.force {
            hit.direction = Some(vec3("--force", f)?);
        }
        Ok(hit)
    }
}
