//! Parameters of every stage, with the paper's defaults. Lengths are fractions
//! of the longest side of the sequence's bounding box unless
//! `absolute_units` is set (docs/method.md §9): the paper's ρ = 0.125 m on a
//! 1.8 m human becomes 0.07, so one default serves millimetres and metres.
//! ρ_p defaults to 1.5 center spacings instead: see [`TrackParams::rho_p`].

use crate::math::Real;

/// Which affinity weights the rigid fits (docs/method.md §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AffinityKind {
    /// The paper's maximum-distance affinity (default).
    Max,
    /// The earlier IIR-filtered affinity of \[8\], kept for comparison.
    Iir,
}

/// The frame whose mesh the result deforms: the centers are placed in it
/// and tracked from it forward to the last frame and backward to the first
/// (`track::reference`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reference {
    /// The frame whose parts are most separate: the most parts less the
    /// tunnels through them (`voxel::FrameTopology::separation`), the
    /// earliest such frame. A take whose first frame shows two things
    /// touching that part later (hands clasped, a ball held, then thrown)
    /// otherwise keeps them joined by a membrane for the rest of the take.
    /// With checkpoints, frame 0 (a checkpoint holds a forward tracking).
    #[default]
    Auto,
    /// Frame 0, as the paper does.
    First,
    /// This frame, counted from 0.
    Frame(usize),
}

/// Forward tracking (docs/method.md §2-§5).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct TrackParams {
    /// Number of centers N. Default 1000; 1 ..= [`MAX_CENTERS`] and at most
    /// the occupied voxels of frame 0.
    pub centers: usize,
    /// Seed of the initial center placement. Default 0.
    pub seed: u64,
    /// Affinity kind. Default [`AffinityKind::Max`].
    pub affinity: AffinityKind,
    /// ρ_p: distance at which the positional affinity is 0.5; > 0. Default
    /// None: [`RHO_P_SPACINGS`] = 1.5 typical center spacings in frame 0,
    /// (occupied volume / N)^(1/3). `Some(ρ)`: ρ relative (or absolute, see
    /// `absolute_units`), e.g. 0.07 for the paper's 0.125 m.
    /// Why smaller than the paper's: on a human at N = 1000 the paper's value
    /// spans several spacings, so a center's rigid fit reaches across joints:
    /// the torso's centers turn with the swinging legs, and nothing pulls
    /// them back because a torso's volume barely changes when it spins about
    /// its own axis. Why spacings and not a fixed fraction: a fixed length is
    /// a fraction of a spacing when few centers fill a small volume, and fits
    /// left with hardly a neighbour each let centers stray.
    pub rho_p: Option<Real>,
    /// ρ_m: motion dissimilarity at which the motion affinity is 0.5.
    /// Default 0.07 (relative; the paper's 0.125 m); in [`LENGTH`].
    pub rho_m: Real,
    /// α: IIR filter weight of the newest motion affinity (`iir` only).
    /// Default 0.05; in (0, 1].
    pub alpha: Real,
    /// β: weight of the centroid (data) term against the rigid prediction.
    /// Default 1; in [`WEIGHT`].
    pub beta: Real,
    /// μ: affinities below this are dropped from the neighbour lists.
    /// Default 0.001; in (0, 1).
    pub mu: Real,
    /// Steps of pure rigid prediction before the data term enters. Default 10;
    /// 0 ..= [`MAX_ROUNDS`].
    pub presmooth_steps: usize,
    /// Convergence: stop when no center moves farther than this in one
    /// iteration. Default 5.6e-5 (relative; the reference's 1e-4 m); in [`LENGTH`].
    /// The iterations stop short of where they lead, on the side of the
    /// guess, so the centers of a body that keeps turning lag its turn a
    /// little; a smaller threshold (1e-5 for a rigid body) narrows the lag
    /// at the cost of more iterations per frame.
    pub threshold: Real,
    /// Iteration limit per frame. Default 1000; 1 ..= [`MAX_ITERATIONS`].
    pub max_iterations: usize,
    /// W: the run toward `threshold` also stops once no center has moved
    /// farther than W × `threshold` over the last W iterations, and then
    /// keeps the state among those W whose largest update was the shortest.
    /// Why: at R = 256 one voxel changing owner moves a cell's centroid by
    /// about the threshold, so once the centers have settled, the
    /// per-iteration test waits, often for hundreds of iterations, for a
    /// moment when no voxel of any cell changes owner, while the centers
    /// only step back and forth in place; a center still drifting moves
    /// W × threshold in W iterations and keeps the run going as before.
    /// Default 8 (docs/measurements.md); 1 is the paper's per-iteration
    /// test alone; 1 ..= [`MAX_ROUNDS`].
    pub convergence_window: usize,
    /// k of a second start for every frame after the first: besides the
    /// paper's constant-velocity guess c^{f-1} + (c^{f-1} − c^{f-2}), the
    /// frame is also tracked from c^{f-1} + k (c^{f-1} − c^{f-2}), and the
    /// runs are compared by their energy E = Es + β Eu (docs/method.md §3),
    /// region by region (see `guess_screening`). Limbs that swing and turn
    /// back within a few frames defeat the constant-velocity guess, all the more when frames are far apart in
    /// time: it sends a hand that has just stopped at the hip into the hip,
    /// its centers stay there, and a forearm follows them. A damped guess
    /// alone loses limbs that start moving at constant velocity instead (feet
    /// lifting off). Keeping the better of the two loses neither. Each guess
    /// adds a run (they share the cores); None, with `accelerated_guess`
    /// false, tracks from the paper's guess alone. Default Some(0.25); in
    /// [0, 1).
    pub damped_guess: Option<Real>,
    /// A start at constant acceleration from frame 3 on, besides the others:
    /// c^{f-1} + v + (v − v') with v = c^{f-1} − c^{f-2}, v' = c^{f-2} −
    /// c^{f-3}. A limb that swings like a pendulum turns back within a few
    /// frames; the constant-velocity guess then sends it on past the turn and
    /// the damped one leaves it behind, both by several of its widths when it
    /// is thin and fast (a galloping animal's legs), and its centers end in
    /// another part. Default true.
    pub accelerated_guess: bool,
    /// With several guesses, their runs stop once no update is as long as
    /// this many times `threshold` (but for `screening_unsettled` of the
    /// centers); they are then compared region by region
    /// and combined, and only the kept run goes on to `threshold`
    /// (`track::forward`). 1 runs every guess to `threshold`. Default 4; in
    /// [1, 1e6].
    pub guess_screening: Real,
    /// The share of the centers whose update may still be longer than
    /// `guess_screening` × `threshold` when the guesses' runs are compared:
    /// the screening stops once no more than this share (rounded down) are.
    /// Why: near the end of a run its updates have shrunk everywhere but
    /// in a few places where centers creep along for dozens of iterations
    /// more, and the screening compares regions, which those few centers
    /// barely change; waiting for the last of them costs many of the
    /// dropped runs' iterations (figures in docs/measurements.md). 0 waits for
    /// every center. Default 0.01; in [0, 1).
    pub screening_unsettled: Real,
    /// With several guesses, their runs up to the screening (and the
    /// combination's) assign blocks of this many voxels along each side,
    /// each block as a whole by its voxels' centroid, instead of single
    /// voxels; the kept run goes on to `threshold` on the voxels. A cell of
    /// blocks has its voxels' exact count and centroid, and a block edge of
    /// 2 leaves far fewer elements to assign, so the tracking is faster
    /// (docs/measurements.md). Not the default: the screened runs stop
    /// where blocks, not voxels, balance, and the correspondence comes out
    /// a little worse on every shared sequence, the galloping trotter's
    /// legs clearly worse (docs/measurements.md). For long captures where
    /// time matters more. Default 1 (voxels); 1 ..= 8.
    pub screening_block: usize,
    /// ω of the tracking iterations: each step moves a center ω times the
    /// way to the paper's update (p + β x̄) / (1 + β); convergence is judged
    /// on that update's length whatever ω, so the iterations stop where the
    /// paper's would, in fewer steps above 1. Not the default: above 1 it
    /// took fewer iterations but tracked every shared sequence a little
    /// worse and the galloping trotter's legs clearly worse
    /// (docs/measurements.md). Default 1 (the paper's iteration); in (0, 2).
    pub tracking_over_relaxation: Real,
    /// Once a frame has converged, find the centers whose cells hold far
    /// less than their frame-0 volume (starved), group them into parts by
    /// their affinity links, and turn each part as one rigid body about
    /// where it hangs from the other centers toward the frame's volume that
    /// no other cell's rigid motion carries there; iterate again, for up to
    /// 3 rounds while each leaves that volume a fifth smaller
    /// (`track::claims`). Why: a thin part that moves several of its widths
    /// in a frame leaves its centers behind with empty cells, which the
    /// centroid term cannot pull, while the cells nearest to where it went
    /// stretch across it; a limb turns about its joint, so turning the
    /// stranded centers together finds where it went and keeps their order
    /// along it. Frames where no cell is starved are tracked as before.
    /// Default true (issue 46: on the generated family it keeps parts that
    /// the paper's tracking loses; the shared sequences are unchanged:
    /// docs/measurements.md); false is the tracking of 657cfbf.
    #[serde(default = "default_reclaim")]
    pub reclaim: bool,
    /// Most Lloyd iterations placing the centers in frame 0; they stop earlier
    /// once no center moves farther than `threshold`. Default 1000 (the
    /// reference runs 100, which leaves frame 0 unconverged: see the
    /// seeding in `track::lloyd`); 1 ..= [`MAX_ITERATIONS`].
    pub lloyd_iterations: usize,
    /// Over-relaxation of those Lloyd iterations (c += ω (x̄ - c)).
    /// Default 1.8; in (0, 2).
    pub over_relaxation: Real,
    /// Take ρ_p, ρ_m and threshold in the input's units instead of as
    /// fractions of the bounding box's longest side. Default false.
    pub absolute_units: bool,
    /// The frame the centers are placed in and tracked from, forward and
    /// backward. Default [`Reference::Auto`]; a given frame must be one of
    /// the sequence's.
    #[serde(default)]
    pub reference: Reference,
}

impl Default for TrackParams {
    fn default() -> Self {
        TrackParams {
            centers: 1000,
            seed: 0,
            affinity: AffinityKind::Max,
            rho_p: None,
            rho_m: 0.07,
            alpha: 0.05,
            beta: 1.0,
            mu: 0.001,
            presmooth_steps: 10,
            threshold: 5.6e-5,
            max_iterations: 1000,
            convergence_window: 8,
            damped_guess: Some(0.25),
            accelerated_guess: true,
            guess_screening: 4.0,
            screening_unsettled: 0.01,
            screening_block: 1,
            tracking_over_relaxation: 1.0,
            reclaim: true,
            lloyd_iterations: 1000,
            over_relaxation: 1.8,
            absolute_units: false,
            reference: Reference::Auto,
        }
    }
}

impl TrackParams {
    /// Checks every field's range.
    pub fn validate(&self) -> crate::Result<()> {
        check_count("the number of centers", self.centers, 1..=MAX_CENTERS)?;
        if let Some(rho_p) = self.rho_p {
            check("rho_p", rho_p, LENGTH)?;
        }
        check("rho_m", self.rho_m, LENGTH)?;
        check("alpha", self.alpha, Span::open_closed(0.0, 1.0))?;
        check("beta", self.beta, WEIGHT)?;
        check("mu", self.mu, Span::open(0.0, 1.0))?;
        check_count(
            "the presmoothing steps",
            self.presmooth_steps,
            0..=MAX_ROUNDS,
        )?;
        check("the convergence threshold", self.threshold, LENGTH)?;
        check_count(
            "the iteration limit per frame",
            self.max_iterations,
            1..=MAX_ITERATIONS,
        )?;
        check_count(
            "the convergence window",
            self.convergence_window,
            1..=MAX_ROUNDS,
        )?;
        check_count("the screening block", self.screening_block, 1..=8)?;
        if let Some(k) = self.damped_guess {
            check("the damped guess's factor", k, Span::closed_open(0.0, 1.0))?;
        }
        check(
            "the tracking over-relaxation",
            self.tracking_over_relaxation,
            Span::open(0.0, 2.0),
        )?;
        check(
            "the guess screening factor",
            self.guess_screening,
            Span::closed(1.0, 1e6),
        )?;
        check(
            "the screening's unsettled share",
            self.screening_unsettled,
            Span::closed_open(0.0, 1.0),
        )?;
        // 0 would leave the centers where the seeding put them, unplaced.
        check_count(
            "the Lloyd iterations",
            self.lloyd_iterations,
            1..=MAX_ITERATIONS,
        )?;
        check(
            "the over-relaxation",
            self.over_relaxation,
            Span::open(0.0, 2.0),
        )?;
        Ok(())
    }

    /// Factor from this struct's lengths to the input's units.
    pub fn length_scale(&self, bounds: &crate::model::mesh::Aabb) -> Real {
        length_scale(self.absolute_units, bounds)
    }

    /// ρ_p in the input's units, for a frame 0 occupying `volume` (in the
    /// input's units cubed) and lengths scaled by `scale`.
    pub(crate) fn rho_p_in_units(&self, scale: Real, volume: Real) -> Real {
        match self.rho_p {
            Some(rho) => rho * scale,
            None => RHO_P_SPACINGS * (volume / self.centers.max(1) as Real).cbrt(),
        }
    }
}

/// ρ_p's default, in typical center spacings (see [`TrackParams::rho_p`]).
/// Fewer, and a center's fit has too few neighbours to hold it to its part;
/// more, and fits reach across joints. Chosen where the centers' error
/// against ground truth was lowest, with both guesses
/// ([`TrackParams::damped_guess`]): small values ask more of the guess, and
/// the constant-velocity guess alone loses fast limbs there with some seeds
/// (it needed about 1.8). The figures are in `docs/measurements.md`.
pub const RHO_P_SPACINGS: Real = 1.5;

/// σ such that exp(-σ ρ²) = 0.5.
pub fn sigma_for(rho: Real) -> Real {
    std::f64::consts::LN_2 / (rho * rho)
}

/// Irregular-center removal and the temporally global optimisation (docs/method.md §6-§7).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RefineParams {
    /// Irregular centers removed in all. Default None = 1 % of N, at least 1;
    /// 0 ..= N - 2.
    pub remove: Option<usize>,
    /// n_go: batches the removal is split into, each followed by one global
    /// optimisation. Default 5; 1 ..= [`MAX_BATCHES`] (n_rem = remove / batches).
    pub batches: usize,
    /// Run the global optimisation after each batch; false = removal only.
    /// Default true.
    pub optimise: bool,
    /// Rank the centers to remove by their irregularity relative to their
    /// spacing in frame 0 (`refine::irregular::relative_irregularity`)
    /// instead of the paper's absolute I_i, which ranks every center of a
    /// sparsely covered part (a thin limb) as the most irregular and so
    /// removes the part. Default true; false is the paper's.
    #[serde(default = "default_relative_irregularity")]
    pub relative_irregularity: bool,
    /// β̂: weight of the centroid term in the global energy. Default 0.5; in [`WEIGHT`].
    pub beta_hat: Real,
    /// ρ_gp: distance (maximum over frames) at which ω_max is 0.5. Default
    /// 0.07 (relative; the paper's 0.125 m); > 0.
    pub rho_gp: Real,
    /// ρ_gm: motion dissimilarity (maximum over frames) at which ω is 0.5.
    /// Default 0.0167 (relative; the paper's 0.03 m); in [`LENGTH`].
    pub rho_gm: Real,
    /// Global iterations per batch. Default 20 (the reference: 30); 0 ..= [`MAX_ITERATIONS`].
    pub max_iterations: usize,
    /// Initial step λ of each iteration. Default 0.1; in [`WEIGHT`].
    pub lambda: Real,
    /// Halvings of λ tried before an iteration gives up. Default 20.
    pub max_halvings: usize,
    /// Affinities below this are dropped. Default 0.001; in (0, 1).
    pub mu: Real,
    /// Lengths in the input's units instead of fractions of the bounding
    /// box's longest side. Default false.
    pub absolute_units: bool,
    /// Bytes of gradient (24 per center and frame) the global optimisation
    /// keeps in memory; past it, a long sequence's gradients (the step's and
    /// the trial's) go to temporary files (in `TMPDIR`) written and read a
    /// block of frames at a time. The result is the same either way, so it
    /// is not recorded with it. Default [`REFINE_GRADIENT_MEMORY`] (16 MiB);
    /// any value.
    #[serde(skip, default = "refine_gradient_memory")]
    pub memory: usize,
    /// Bytes of cell assignments the global optimisation keeps between its
    /// evaluations ([`KEPT_CELL_BYTES_PER_VOXEL`] per occupied voxel of a
    /// kept frame), for at most [`KEPT_CELL_FRAMES`] frames; the frames
    /// past it are assigned afresh at each evaluation, which gives the same
    /// cells much more slowly, so it is not recorded with the result. Why a
    /// budget in bytes: a solid object at a high resolution has millions of
    /// voxels a frame, and 64 frames of them would need tens of GiB. None
    /// (default): half the memory available when the refinement
    /// starts, or of `--max-memory` when given (1 GiB where unknown); in
    /// [`MEMORY`].
    #[serde(skip)]
    pub cell_memory: Option<f64>,
}

/// [`RefineParams::memory`]'s default: 16 MiB, some 700 frames of 1,000
/// centers. Each gradient is written once and read twice per evaluation,
/// which costs little beside assigning every frame's cells.
pub const REFINE_GRADIENT_MEMORY: usize = 16 << 20;

fn default_reclaim() -> bool {
    TrackParams::default().reclaim
}

fn default_relative_irregularity() -> bool {
    true
}

fn refine_gradient_memory() -> usize {
    REFINE_GRADIENT_MEMORY
}

impl Default for RefineParams {
    fn default() -> Self {
        RefineParams {
            remove: None,
            batches: 5,
            optimise: true,
            relative_irregularity: true,
            beta_hat: 0.5,
            rho_gp: 0.07,
            rho_gm: 0.0167,
            max_iterations: 20,
            lambda: 0.1,
            max_halvings: 20,
            mu: 0.001,
            absolute_units: false,
            memory: REFINE_GRADIENT_MEMORY,
            cell_memory: None,
        }
    }
}

impl RefineParams {
    /// These parameters under a limit of `max_memory` bytes for the run,
    /// when there is one: unless `cell_memory` is set, the kept cells take
    /// their share of it ([`KEPT_CELL_SHARE`]) instead of the memory available.
    pub fn within(self, max_memory: Option<f64>) -> Self {
        RefineParams {
            cell_memory: self.cell_memory.or(max_memory.map(kept_cell_share)),
            ..self
        }
    }

    /// Centers removed in all for `n` centers.
    pub(crate) fn total_removed(&self, n: usize) -> usize {
        self.remove.unwrap_or((n / 100).max(1))
    }

    /// Checks every field's range for `n` tracked centers.
    pub fn validate(&self, n: usize) -> crate::Result<()> {
        let bad = |what: String| Err(crate::Error::InvalidParameter(what));
        if n < 3 {
            return bad(format!(
                "refinement removes at least 1 irregular center and keeps at least 2, so it needs at least 3 centers, not {n}; track more centers or skip refinement"
            ));
        }
        if self.total_removed(n).saturating_add(2) > n {
            return bad(format!(
                "cannot remove {} of {n} centers: at most {} (2 must stay)",
                self.total_removed(n),
                n - 2
            ));
        }
        check_count("the number of batches", self.batches, 1..=MAX_BATCHES)?;
        if let Some(m) = self.cell_memory {
            check("the memory for kept cells", m, MEMORY)?;
        }
        check("beta_hat", self.beta_hat, WEIGHT)?;
        check("rho_gp", self.rho_gp, LENGTH)?;
        check("rho_gm", self.rho_gm, LENGTH)?;
        check_count(
            "the global iterations per batch",
            self.max_iterations,
            0..=MAX_ITERATIONS,
        )?;
        check("lambda", self.lambda, WEIGHT)?;
        check_count("the step halvings", self.max_halvings, 0..=60)?;
        check("mu", self.mu, Span::open(0.0, 1.0))?;
        Ok(())
    }

    /// Factor from this struct's lengths to the input's units.
    pub fn length_scale(&self, bounds: &crate::model::mesh::Aabb) -> Real {
        length_scale(self.absolute_units, bounds)
    }
}

/// How a vertex combines its centers' motions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Blending {
    /// Dual-quaternion blending: no collapse at twisting joints (default).
    DualQuaternion,
    /// Linear blending of the transformed positions.
    Linear,
}

/// Deforming the first-frame mesh by the trajectories (docs/method.md §10).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DeformParams {
    /// Centers each vertex is bound to. Default 4; 1 ..= [`MAX_NEIGHBORS`].
    pub neighbors: usize,
    /// Least ω between a vertex's nearest center and another center for the
    /// vertex to bind to it too. Default 0.5; in (0, 1].
    pub min_affinity: Real,
    /// Rounds of spreading every vertex's center weights over its mesh
    /// neighbours (half its own, half their mean), keeping the
    /// `2 × neighbors` largest. Without it the center set switches between
    /// adjacent vertices where the ω filter cuts, and triangles across the
    /// cut fold. Default 10; 0 = off; at most [`MAX_ROUNDS`].
    pub smoothing: usize,
    /// Blending. Default dual quaternions.
    pub blending: Blending,
    /// Bytes of vertex positions the dynamic mesh keeps in memory (24 per
    /// vertex and frame); a longer sequence's frames go to a temporary file
    /// (in `TMPDIR`) and are read back a few at a time by conforming and
    /// export, so memory stops growing with the frames. The output is the
    /// same either way. Default [`DYNAMIC_MESH_MEMORY`] (16 MiB); any value.
    pub memory: usize,
    /// Cut the take where its solid's parts merge or part, and deform a
    /// mesh of each stretch's own (`deform::segments`): one frame's mesh keeps
    /// its parts, so merged surfaces would stay (hidden) or parted ones be
    /// joined by a membrane. Meshes with texture coordinates keep one mesh
    /// (their textures cannot be joined). Default true.
    pub segments: bool,
}

/// [`DeformParams::memory`]'s default: 16 MiB, some 700 frames of a
/// 1,000-vertex mesh or 11 of a 60,000-vertex one. Reading frames back from
/// the file costs little (the system keeps them cached while memory allows),
/// so the limit is low: memory then stops growing with the frames early.
pub const DYNAMIC_MESH_MEMORY: usize = 16 << 20;

impl DeformParams {
    /// Checks every field's range.
    pub fn validate(&self) -> crate::Result<()> {
        check_count(
            "the centers each vertex follows",
            self.neighbors,
            1..=MAX_NEIGHBORS,
        )?;
        check(
            "the least binding affinity",
            self.min_affinity,
            Span::open_closed(0.0, 1.0),
        )?;
        check_count(
            "the binding smoothing rounds",
            self.smoothing,
            0..=MAX_ROUNDS,
        )?;
        Ok(())
    }
}

impl Default for DeformParams {
    fn default() -> Self {
        DeformParams {
            neighbors: 4,
            min_affinity: 0.5,
            smoothing: 10,
            blending: Blending::DualQuaternion,
            memory: DYNAMIC_MESH_MEMORY,
            segments: true,
        }
    }
}

/// Lengths are fractions of the bounding box's longest side (docs/method.md §9)
/// unless given in the input's units.
fn length_scale(absolute_units: bool, bounds: &crate::model::mesh::Aabb) -> Real {
    if absolute_units {
        1.0
    } else {
        bounds.longest_side()
    }
}

/// Fitting the deformed mesh to every frame's input surface (not in the
/// paper): per frame, an as-rigid-as-possible deformation of the frame-0
/// mesh, started from the blended result of docs/method.md §10 and pulled
/// through the vertices of that frame's input (each input vertex pulls the
/// mesh's nearest compatible point; `deform::conform` says why not onto the
/// input's triangles).
///
/// Why: a volume tracker barely sees the skin slide over a joint or a body
/// spin about its own axis, and blending leaves folds where bound centers
/// disagree. Keeping the mesh's edges as in frame 0 while it lies on the
/// input surface corrects both: the vertices follow the surface's true
/// motion more closely and fewer triangles fold, and a rigid body re-meshed
/// per frame keeps closer to its rigid motion.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ConformParams {
    /// Rounds of (rotations, matching the input's vertices, solve) per
    /// frame: the mesh slides along the surface slowly, so more rounds keep
    /// helping a little. Default 60; 0 = off (the mesh stays as blended); at
    /// most [`MAX_ROUNDS`].
    pub iterations: usize,
    /// Weight of keeping every edge as in frame 0 (up to a rotation per
    /// vertex) against passing through the input's vertices. Larger:
    /// stiffer, fits the surface less closely. Default 1; in [`WEIGHT`].
    pub stiffness: Real,
    /// Share of the full distance to an input vertex next to the distance
    /// along the mesh's normal: small lets the mesh slide along the
    /// surface to where its edges keep their lengths (the nearest point is
    /// not the input vertex's match, so pulling along the surface biases
    /// the fit). Default 0.03; >= 0.
    pub point_weight: Real,
    /// Farthest an input vertex pulls the mesh from, as a fraction of the
    /// bounding box's longest side (or in the input's units with
    /// `absolute_units`): farther vertices belong to another part. Default
    /// 0.025; > 0.
    pub max_distance: Real,
    /// Least cosine between the normal of the mesh's triangle an input
    /// vertex pulls and the normal of every input triangle at that vertex,
    /// so a surface is never pulled onto the back of another one it
    /// touches, and a vertex whose triangles turn across a crease they cut
    /// pulls only mesh triangles facing close to all of them. Default 0.7
    /// (46°); in [-1, 1]. Lower lets more input vertices pull, which fits a
    /// smoothly deforming body a little closer; higher keeps the vertices
    /// beside a crease from pulling the sides, which keeps a rigid body
    /// truer.
    pub min_normal_cosine: Real,
    /// Strain of an edge (how far it is from its frame-0 vector turned by
    /// its vertices' rotations, over its length) at which its rigidity
    /// weighs half, in the fit's last two thirds of rounds: edges strained
    /// more weigh less, so a joint's bend gathers at the edges across it
    /// instead of bending the rigid parts beside it. Default 0.2; >= 0, 0
    /// weighs every edge alike.
    #[serde(default = "default_bend_strain")]
    pub bend_strain: Real,
    /// Least weight of a strained edge, against 1 for an unstrained one:
    /// keeps a strongly bent joint from folding over. Default 0.3; in (0, 1].
    #[serde(default = "default_least_edge_weight")]
    pub least_edge_weight: Real,
    /// Mean strain of an edge, over a first fit of up to 16 frames spread
    /// over the take, at which its rigidity weighs half in every frame's
    /// fit (times the frame's own weight from `bend_strain`): a joint bends
    /// at the same edges through the take, a frame's own strains are partly
    /// its noise. Default 0.07; >= 0, 0 skips the first fit (every frame
    /// then finds its joints alone).
    #[serde(default = "default_joint_strain")]
    pub joint_strain: Real,
    /// Least weight of an edge from its mean strain: with the frame's own
    /// at least `least_edge_weight`, an edge weighs at least their product.
    /// Default 0.15; in (0, 1].
    #[serde(default = "default_least_joint_weight")]
    pub least_joint_weight: Real,
    /// Lengths in the input's units instead of fractions of the longest side.
    pub absolute_units: bool,
}

fn default_bend_strain() -> Real {
    ConformParams::default().bend_strain
}

fn default_least_edge_weight() -> Real {
    ConformParams::default().least_edge_weight
}

fn default_joint_strain() -> Real {
    ConformParams::default().joint_strain
}

fn default_least_joint_weight() -> Real {
    ConformParams::default().least_joint_weight
}

impl Default for ConformParams {
    fn default() -> Self {
        ConformParams {
            iterations: 60,
            stiffness: 1.0,
            point_weight: 0.03,
            max_distance: 0.025,
            min_normal_cosine: 0.7,
            bend_strain: 0.2,
            least_edge_weight: 0.3,
            joint_strain: 0.07,
            least_joint_weight: 0.15,
            absolute_units: false,
        }
    }
}

impl ConformParams {
    /// Checks every field's range.
    pub fn validate(&self) -> crate::Result<()> {
        check_count("the conform iterations", self.iterations, 0..=MAX_ROUNDS)?;
        check("the conform stiffness", self.stiffness, WEIGHT)?;
        check(
            "the conform point weight",
            self.point_weight,
            Span::closed(0.0, WEIGHT.hi),
        )?;
        check("the conform distance", self.max_distance, LENGTH)?;
        check(
            "the conform normal cosine",
            self.min_normal_cosine,
            Span::closed(-1.0, 1.0),
        )?;
        check(
            "the conform bend strain",
            self.bend_strain,
            Span::closed(0.0, WEIGHT.hi),
        )?;
        check(
            "the conform least edge weight",
            self.least_edge_weight,
            Span::open_closed(0.0, 1.0),
        )?;
        check(
            "the conform joint strain",
            self.joint_strain,
            Span::closed(0.0, WEIGHT.hi),
        )?;
        check(
            "the conform least joint weight",
            self.least_joint_weight,
            Span::open_closed(0.0, 1.0),
        )?;
        Ok(())
    }

    /// Factor from this struct's lengths to the input's units.
    pub fn length_scale(&self, bounds: &crate::model::mesh::Aabb) -> Real {
        length_scale(self.absolute_units, bounds)
    }
}

/// Warning of parts the tracker lost (`metrics::coverage`; not in
/// the paper): frames with input volume no tracked cell reaches, or whose
/// fit to the input is far worse than the sequence's usual.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CoverageParams {
    /// A voxel is unreached when it lies farther from its cell's center
    /// than this many times the cell's frame-0 reach (the distance to its
    /// farthest voxel then). Default 2; in [1, 1e6].
    pub reach: Real,
    /// Smallest connected region of unreached voxels counted as lost, in
    /// cells' volume (frame 0's occupied voxels / N). Default 2; in [0, 1e6].
    pub min_region: Real,
    /// A frame is flagged when the lost volume is at least this share of
    /// its occupied volume. Default 0.005 (half a thin limb of a figure;
    /// the shared captures whose parts are all kept reach 0.0027,
    /// docs/measurements.md); in (0, 1].
    pub min_share: Real,
    /// A frame's fit to the input (the 95th percentile of its two-sided
    /// distance, `metrics::FrameFit::two_sided`) is flagged when it
    /// is more than this many times the sequence's usual fit, the lower
    /// quartile over the frames after the first (the quartile, not the
    /// median: a lost part often stays lost to the end, so the bad frames
    /// can be the majority)... Default 4; in [1, 1e6].
    pub fit_ratio: Real,
    /// ... and more than this, in percent of the bounding-box diagonal (so a
    /// sequence fitted closely everywhere is never flagged). Default 2; in
    /// [0, 1e6].
    pub fit_floor: Real,
    /// A region of the input's surface farther than this from the result,
    /// in percent of the bounding-box diagonal, is far: a part the result
    /// lost (`metrics::FrameFit::far_input`). Default 2; in (0, 1e6].
    #[serde(default = "default_far")]
    pub far: Real,
    /// The same for a region of the result's surface outside the input's
    /// volume: a part carried or torn where the input has none
    /// (`metrics::FrameFit::far_result`). Farther than `far`, since a
    /// result's extremities overshoot the input's by a few percent where
    /// the rest fits (hooves and toes on the shared captures, measured in
    /// docs/measurements.md). Default 5; in (0, 1e6].
    #[serde(default = "default_far_result")]
    pub far_result: Real,
    /// ... and never nearer than this many voxels: a surface rebuilt from
    /// voxels is a voxel or so off anywhere, more at sharp creases, so at a
    /// low resolution the percentage alone would call that a lost part.
    /// Default 3; in [0, 1e6].
    #[serde(default = "default_far_voxels")]
    pub far_voxels: Real,
    /// A frame is flagged when a connected far region covers at least this
    /// share of its surface, in percent. Default 0.1; in [0, 100].
    #[serde(default = "default_far_share")]
    pub far_share: Real,
    /// A frame next to a warned one is warned too where a region as large
    /// lies past this share of `far` and `far_result` (the voxel floor
    /// unchanged), and so on along the take: a lost part stays lost for
    /// frames, and in those where it goes and comes back it is less far,
    /// so weaker evidence carries a warning on but never starts one (the
    /// hysteresis of an edge detector; `metrics::LostParts::continued`).
    /// Default 0.5; in (0, 1], where 1 carries nothing on.
    #[serde(default = "default_weak")]
    pub weak: Real,
    /// A region of the result's surface outside the input's volume, as
    /// large as `far_share` and past this share of `far_result` (the voxel
    /// floor unchanged), in at least `lasting_frames` frames in a row, is
    /// warned of in each of them: a part the tracking moved off the
    /// input's stays off for frames, where an extremity overshoots the
    /// input's for a frame or two (`metrics::LostParts::lasting`).
    /// Default 0.6; in (0, 1], where 1 adds nothing.
    #[serde(default = "default_lasting")]
    pub lasting: Real,
    /// See `lasting`. Default 5; in [1, 10000].
    #[serde(default = "default_lasting_frames")]
    pub lasting_frames: usize,
}

fn default_far() -> Real {
    CoverageParams::default().far
}

fn default_far_result() -> Real {
    CoverageParams::default().far_result
}

fn default_far_voxels() -> Real {
    CoverageParams::default().far_voxels
}

fn default_far_share() -> Real {
    CoverageParams::default().far_share
}

fn default_weak() -> Real {
    CoverageParams::default().weak
}

fn default_lasting() -> Real {
    CoverageParams::default().lasting
}

fn default_lasting_frames() -> usize {
    CoverageParams::default().lasting_frames
}

impl Default for CoverageParams {
    fn default() -> Self {
        CoverageParams {
            reach: 2.0,
            min_region: 2.0,
            min_share: 0.005,
            fit_ratio: 4.0,
            fit_floor: 2.0,
            far: 2.0,
            far_result: 5.0,
            far_voxels: 3.0,
            far_share: 0.1,
            weak: 0.5,
            lasting: 0.6,
            lasting_frames: 5,
        }
    }
}

/// How far a region of each surface must lie from the other to count as
/// far, in percent of the diagonal (`metrics::FrameFit::far_input` and `far_result`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FarDistances {
    /// For the input's surface: a part the result lost.
    pub input: Real,
    /// For the result's surface: a part carried or torn where the input has none.
    pub result: Real,
    /// The weaker distances that carry a warning on to the next frame
    /// ([`CoverageParams::weak`]): for the input's surface...
    pub weak_input: Real,
    /// ... and for the result's.
    pub weak_result: Real,
    /// The distance past which a region of the result's surface that
    /// lasts for frames is warned of ([`CoverageParams::lasting`]).
    pub lasting_result: Real,
}

impl FarDistances {
    /// The same distance both ways, and no weaker one.
    pub fn both(far: Real) -> Self {
        FarDistances::of(far, far)
    }

    /// `input` and `result`, and no weaker ones.
    pub fn of(input: Real, result: Real) -> Self {
        FarDistances {
            input,
            result,
            weak_input: input,
            weak_result: result,
            lasting_result: result,
        }
    }
}

impl CoverageParams {
    /// The distances past which a region is far, in percent of `diagonal`:
    /// `far` and `far_result`, or `far_voxels` voxels of `voxel_size` where
    /// that is more; the weaker ones, `weak` times those or the same floor;
    /// and `lasting` times `far_result` or that floor.
    pub fn far_distances(&self, diagonal: Real, voxel_size: Real) -> FarDistances {
        let floor = 100.0 * self.far_voxels * voxel_size / diagonal;
        FarDistances {
            input: self.far.max(floor),
            result: self.far_result.max(floor),
            weak_input: (self.weak * self.far).max(floor),
            weak_result: (self.weak * self.far_result).max(floor),
            lasting_result: (self.lasting * self.far_result).max(floor),
        }
    }

    /// Checks every field's range.
    pub fn validate(&self) -> crate::Result<()> {
        check("the coverage reach", self.reach, Span::closed(1.0, 1e6))?;
        check(
            "the smallest lost region",
            self.min_region,
            Span::closed(0.0, 1e6),
        )?;
        check(
            "the least lost share",
            self.min_share,
            Span::open_closed(0.0, 1.0),
        )?;
        check("the fit ratio", self.fit_ratio, Span::closed(1.0, 1e6))?;
        check("the fit floor", self.fit_floor, Span::closed(0.0, 1e6))?;
        check("the far distance", self.far, Span::open_closed(0.0, 1e6))?;
        check(
            "the result's far distance",
            self.far_result,
            Span::open_closed(0.0, 1e6),
        )?;
        check(
            "the far distance in voxels",
            self.far_voxels,
            Span::closed(0.0, 1e6),
        )?;
        check(
            "the far region share",
            self.far_share,
            Span::closed(0.0, 100.0),
        )?;
        check(
            "the weak share of the far distances",
            self.weak,
            Span::open_closed(0.0, 1.0),
        )?;
        check(
            "the lasting share of the result's far distance",
            self.lasting,
            Span::open_closed(0.0, 1.0),
        )?;
        check_count(
            "the frames a lasting far region needs",
            self.lasting_frames,
            1..=10_000,
        )?;
        Ok(())
    }
}

/// Frames whose Voronoi cell assignments the global optimisation keeps
/// between its steps (`refine::SequenceCells`): every frame of a sequence
/// this short, a fixed number of a longer one, whose other frames are
/// assigned afresh at each step, so that memory does not grow with the
/// sequence.
pub const KEPT_CELL_FRAMES: usize = 64;

/// Bytes a kept cell assignment takes per occupied voxel: owner, distance
/// bounds and coordinates (18; no runner-ups), with room for the update's
/// working lists.
pub const KEPT_CELL_BYTES_PER_VOXEL: usize = 24;

/// The share of the memory allowed that [`RefineParams::cell_memory`] takes
/// by default.
pub const KEPT_CELL_SHARE: f64 = 0.5;

/// The bytes the kept cell assignments may take under a limit of `limit`
/// bytes, unless told otherwise ([`KEPT_CELL_SHARE`]).
pub fn kept_cell_share(limit: f64) -> f64 {
    limit * KEPT_CELL_SHARE
}

/// Largest number of centers: far more than any capture needs, small enough
/// that per-center tables stay addressable.
pub const MAX_CENTERS: usize = 1_000_000;
/// Largest iteration or round count any stage accepts.
pub const MAX_ITERATIONS: usize = 100_000;
/// Largest number of refinement batches (each one a global optimisation).
pub const MAX_BATCHES: usize = 100;
/// Largest number of rounds of the steps that run every round to the end
/// (presmoothing, binding smoothing, conforming), unlike the iterations that
/// stop once converged.
pub const MAX_ROUNDS: usize = 1_000;
/// Largest number of centers a vertex may follow.
pub const MAX_NEIGHBORS: usize = 64;

/// Every length (ρ, thresholds, distances), relative or in the input's units:
/// beyond these, squares and inverses of squares leave f64's range.
pub const LENGTH: Span = Span::closed(1e-12, 1e12);
/// Every weight or step size (β, β̂, λ, stiffness): larger would overflow
/// the weighted sums it scales.
pub const WEIGHT: Span = Span::open_closed(0.0, 1e6);

/// Range of a memory limit, in bytes: up to 1e9 GiB.
pub const MEMORY: Span = Span::open_closed(0.0, 1e9 * (1u64 << 30) as Real);

/// A range of a real parameter, each end open or closed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Lower end.
    pub lo: Real,
    /// Upper end.
    pub hi: Real,
    /// Whether `lo` itself is outside the span.
    pub lo_open: bool,
    /// Whether `hi` itself is outside the span.
    pub hi_open: bool,
}

impl Span {
    /// `[lo, hi]`: both ends included.
    pub const fn closed(lo: Real, hi: Real) -> Self {
        Span {
            lo,
            hi,
            lo_open: false,
            hi_open: false,
        }
    }
    /// `(lo, hi)`: both ends excluded.
    pub const fn open(lo: Real, hi: Real) -> Self {
        Span {
            lo,
            hi,
            lo_open: true,
            hi_open: true,
        }
    }
    /// `(lo, hi]`: `lo` excluded, `hi` included.
    pub const fn open_closed(lo: Real, hi: Real) -> Self {
        Span {
            lo,
            hi,
            lo_open: true,
            hi_open: false,
        }
    }
    /// `[lo, hi)`: `lo` included, `hi` excluded.
    pub const fn closed_open(lo: Real, hi: Real) -> Self {
        Span {
            lo,
            hi,
            lo_open: false,
            hi_open: true,
        }
    }
    /// Whether `v` lies in the span (never for NaN).
    pub fn contains(&self, v: Real) -> bool {
        let above = if self.lo_open {
            v > self.lo
        } else {
            v >= self.lo
        };
        let below = if self.hi_open {
            v < self.hi
        } else {
            v <= self.hi
        };
        above && below
    }
}

impl std::fmt::Display for Span {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (l, r) = (
            if self.lo_open { '(' } else { '[' },
            if self.hi_open { ')' } else { ']' },
        );
        write!(f, "{l}{}, {}{r}", shown(self.lo), shown(self.hi))
    }
}

/// A number as a user reads it in a message: plain, or in exponent form
/// when very large or very small ("1e6", "1e-12", but "0.5" and "0").
fn shown(x: Real) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        x.to_string()
    }
}

/// Fails unless `value` is in `span`.
pub(crate) fn check(name: &str, value: Real, span: Span) -> crate::Result<()> {
    if span.contains(value) {
        Ok(())
    } else {
        Err(crate::Error::InvalidParameter(format!(
            "{name}: {} is outside {span}",
            shown(value)
        )))
    }
}

/// Fails unless the count `value` is in `range`.
pub(crate) fn check_count(
    name: &str,
    value: usize,
    range: std::ops::RangeInclusive<usize>,
) -> crate::Result<()> {
    if range.contains(&value) {
        Ok(())
    } else {
        Err(crate::Error::InvalidParameter(format!(
            "{name}: {value} is outside {}..={}",
            range.start(),
            range.end()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Range errors show the value and the bounds as a user would write
    /// them: plain, in exponent form only when very large or very small.
    #[test]
    fn range_errors_show_numbers_as_written() {
        let err = TrackParams {
            damped_guess: Some(1.0),
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("the damped guess's factor: 1 is outside [0, 1)"),
            "{err}"
        );
        let err = TrackParams {
            threshold: 1e-13,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(err.contains("1e-13 is outside [1e-12, 1e12]"), "{err}");
        let err = TrackParams {
            screening_unsettled: 1.0,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("unsettled share: 1 is outside [0, 1)"),
            "{err}"
        );
    }
}
