#pragma once
/// \file scene.h
/// Drape scenes: a JSON file naming the body, the collider, the garment, the cloth material, the solver settings and
/// the list of effects. Only listed effects are built and stepped (docs/DESIGN.md sec. 4). Every unknown key and every
/// bad value is a bodyfit::FormatError whose one-line message names the file and the key path, e.g.
/// `demos/scenes/skirt.json: effects[1].wind.velocity: expected an array of 3 numbers`.
///
/// Relative paths in a scene are relative to the scene file's directory.

#include "bodyfit/fitting/mesh_io.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace bodyfit::drape
{

/// Physical ranges of scene values (docs/ROBUSTNESS.md 7.9-7.10). Values outside them are FormatErrors: they used
/// to be accepted and produced NaN nodes (a patch at 1e6 m, a 1e-9 m patch or tube) or launched the cloth (200 m/s
/// wind with air 2,000 times denser than air, keyframes 1e-7 s apart, a loop that jumps).
constexpr double kMaxSceneCoordinate = 1000.0; ///< positions and offsets (m); as a fit file's (ellipsoid_io.h)
constexpr double kMinGarmentSize = 0.01;       ///< patch sides, tube length (m); tube radius half of it
constexpr double kMinGarmentScale = 0.01;      ///< skirt/tights scale factor
constexpr int kMaxGarmentSubdivisions = 3;     ///< skirt/tights garment.subdivide (each: 4x the faces)
constexpr double kMinClothEdge = 1e-4;         ///< generated cloth edge length (m)
constexpr double kMaxWindSpeed = 50.0;         ///< per component (m/s); hurricane force is 33 m/s
constexpr double kMaxTurbulence = 20.0;        ///< noise amplitude (m/s per component)
constexpr double kMaxAirDensity = 5.0;         ///< kg/m^3 (air: 1.2)
constexpr double kMaxAeroCoefficient = 10.0;   ///< lift, drag (flat plate: about 1.2)
constexpr double kMaxBodySpeed = 10.0;         ///< keyframed body translation (m/s; a sprinter)
constexpr double kMaxBodyTurnRate = 720.0;     ///< keyframed body rotation (deg/s)

enum class ColliderKind
{
	Ellipsoids,         ///< our analytic ellipsoid-compound cloth collider (bullet_ext)
	MeshBvh,            ///< Bullet's btBvhTriangleMeshShape of the body mesh, default soft-body SDF_RS path
	ConvexHullCompound, ///< btCompoundShape of btConvexHullShape, one hull per ellipsoid's nearest body vertices
	EllipsoidsSdf,      ///< the btEllipsoidCompoundShape through Bullet's default SDF_RS path (no collider installed)
	None,               ///< no body collider at all
};
const char* toString(ColliderKind kind);
/// \throws FormatError (message "collider kind 'x' ...") for an unknown name.
ColliderKind colliderKindFromString(const std::string& name);

constexpr double kMaxAnimationSpeed = 10.0;    ///< body.animation.speed: clip seconds per simulated second

/// An animated body (body.animation): a rigged file (glTF/GLB, FBX, ...; bodyfit/fitting/rig.h) and one of its
/// clips. The body is the rig's skinned mesh; its ellipsoids are the bind-pose fit (body.ellipsoids: a fit file with
/// a "skinning" section from `bodyfit-fit RIG.glb`, or fitted at load with body.fit / the defaults) bound to the
/// bones, updated at every substep (bodyfit/bridge/btSkinnedBodyDriver.h).
struct AnimationSpec
{
	std::string file;        ///< the rig (absolute path after parsing)
	std::string clip = "0";  ///< clip name, or its index in decimal (JSON: a string or an integer); default the first
	double speed = 1.0;      ///< (0, kMaxAnimationSpeed]
	bool loop = true;        ///< wrap at the clip's end (false: hold the last pose)
	double startS = 0.0;     ///< clip time at simulation time 0 (checked against the clip's duration at load)
};

struct BodySpec
{
	std::string mesh;                 ///< body mesh (absolute path after parsing); the rig file when animated
	std::string ellipsoids;           ///< fitted ellipsoid JSON (absolute), empty when `fit` is given instead
	/// Fit parameters when no ellipsoid file is given: mu_torso, mu_limbs (fractions of the body height, metres with
	/// "absolute": true), max_ellipsoids; run through the fit pipeline (fitting/include/bodyfit/fitting/fit_pipeline.h).
	std::optional<nlohmann::json> fit;
	UpAxis up = UpAxis::Y;
	double scale = 1.0;
	std::optional<AnimationSpec> animation; ///< body.animation; then `mesh` is not given (it is the rig's)
};

struct ColliderSpec
{
	ColliderKind kind = ColliderKind::Ellipsoids;
	double skinOffset = 0.002;   ///< ellipsoids: distance a node is placed outside the surface (m)
	double sdfVoxel = 0.02;      ///< Bullet paths: sparse-SDF voxel size (m); Bullet's default 0.25 is far too coarse
	double shapeMargin = 0.004;  ///< Bullet paths: collision margin of the body shape (m; ellipsoids-sdf: per child)
	double contactHardness = 1.0;///< Bullet paths: kKHR (static/kinematic contact hardness); Bullet's default 0.1 sinks
	/// ellipsoids: "tight" (default) decides contact on the body's skin field (the fit's side file, or baked at load)
	/// inside the union; "ellipsoids" is the paper's pure ellipsoid response. Animated bodies use the ellipsoids.
	bool tightSurface = true;
	/// ellipsoids, tight surface, animated body: also decide the joints on the skinned mesh of the instant
	/// (btSkinnedBodyDriver::setSkinMeshEnabled; default false, see its cost and limit there).
	bool skinMesh = false;
	/// ellipsoids, tight surface, body at rest or moving rigidly: lift cloth edges off the skin (Config::m_liftEdges;
	/// default true; false keeps nodes at the skin offset, and long edges over curved skin then sag into it).
	bool liftEdges = true;
	/// how far lifted edges clear the skin, a fraction of the skin offset in (0, 1] (Config::m_liftClearance)
	double liftClearance = 0.5;
};

enum class GarmentType
{
	Patch,
	BulletPatch, ///< Bullet's btSoftBodyHelpers::CreatePatch: the patch of Bullet's demos (see garment.h)
	Skirt,
	Tights,
	Tube,
};
const char* toString(GarmentType type);

struct GarmentSpec
{
	GarmentType type = GarmentType::Patch;
	// patch, bullet_patch: horizontal rectangle (x by z) centred at `center`
	Eigen::Vector2d size{1.0, 1.0};
	Eigen::Vector2i resolution{31, 31};
	// skirt / tights: mesh from the assets, transformed as p' = scaleCenter + scale * (p - scaleCenter) + offset
	std::string mesh;           ///< absolute path after parsing
	Eigen::Vector3d scale{1.0, 1.0, 1.0};
	std::optional<Eigen::Vector3d> scaleCenter; ///< default: the centroid of the garment's vertices
	Eigen::Vector3d offset = Eigen::Vector3d::Zero();
	/// garment.subdivide: midpoint subdivisions of the mesh after loading and scaling (0..3; each: 4x the faces, every
	/// edge halved, the same surface).
	/// A coarse garment's edges sag into curved skin between their nodes; halving them lets the cloth rest closer.
	int subdivisions = 0;
	// tube: open cylinder along +y
	double radius = 0.2;
	double length = 0.5;
	int segments = 32;          ///< around
	int rings = 16;             ///< along
	Eigen::Vector3d center = Eigen::Vector3d::Zero(); ///< patch and tube centre
};

struct MaterialSpec
{
	double stretch = 0.9;    ///< linear stiffness of structural links, 0..1 (Bullet kLST)
	double bending = 0.2;    ///< linear stiffness of bending links (across each interior edge), 0..1; 0 = none
	double damping = 0.01;   ///< Bullet kDP, 0..1
	double mass = 0.3;       ///< total cloth mass (kg), distributed by face area
	double margin = 0.005;   ///< soft-body collision margin (m); Bullet's default 0.25 is far too coarse
};

struct SolverSpec
{
	double dt = 1.0 / 120.0;  ///< seconds per step
	int substeps = 1;         ///< Bullet internal steps per step (dt / substeps each)
	int iterations = 10;      ///< position iterations (Bullet piterations)
	int steps = 240;          ///< default run length (overridden by --steps)
};

struct GravitySpec
{
	Eigen::Vector3d acceleration{0.0, -9.81, 0.0};
};

struct WindSpec
{
	Eigen::Vector3d velocity{2.0, 0.0, 0.0}; ///< steady component (m/s)
	double turbulence = 1.0;                 ///< noise amplitude (m/s per component)
	double lengthScale = 0.3;                ///< spatial correlation length of the noise (m)
	double timeScale = 0.5;                  ///< temporal correlation time of the noise (s)
	int octaves = 2;                         ///< noise octaves (each half the length and time scale, half the amplitude)
	unsigned seed = 1;
	double drag = 0.6;                       ///< drag coefficient used when `aerodynamics` is not listed
};

struct AerodynamicsSpec
{
	std::string model = "V_TwoSidedLiftDrag"; ///< Bullet eAeroModel name
	double lift = 0.05;                       ///< Bullet kLF
	double drag = 0.4;                        ///< Bullet kDG
	double airDensity = 1.2;                  ///< kg/m^3 (btSoftBodyWorldInfo::air_density)
};

struct FrictionSpec
{
	double coefficient = 0.5; ///< Coulomb coefficient between cloth and body
};

struct SelfCollisionSpec
{
	double thickness = 0.006; ///< minimum distance kept between non-neighbouring cloth nodes (m)
	double stiffness = 0.5;   ///< fraction of the overlap removed per step, 0..1
};

enum class PinSelect
{
	Corners,  ///< patch only: the four corners
	Edge,     ///< patch only: one whole edge (`side`: "-x", "+x", "-z" or "+z")
	Top,      ///< nodes within `band` of the highest node (waistbands)
	Indices,  ///< explicit node indices
};

struct PinSpec
{
	PinSelect select = PinSelect::Corners;
	std::string side = "-x";
	double band = 0.01;
	std::vector<int> indices;
	bool toBody = false; ///< the pinned nodes follow the body (body_motion) instead of staying fixed in the world
};

struct Keyframe
{
	double time = 0.0;
	Eigen::Vector3d translation = Eigen::Vector3d::Zero();
	Eigen::Vector3d axis{0.0, 1.0, 0.0};
	double angleDeg = 0.0;
};

struct BodyMotionSpec
{
	std::vector<Keyframe> keyframes; ///< strictly increasing times; translation lerp, rotation slerp
	std::optional<Eigen::Vector3d> pivot; ///< rotation centre in body coordinates (default: bounding-box centre)
	bool loop = false;                ///< repeat the keyframe cycle (last key time = period)
};

/// The effects a scene lists. An absent optional means the effect is not built at all.
struct EffectsSpec
{
	std::optional<GravitySpec> gravity;
	std::optional<WindSpec> wind;
	std::optional<AerodynamicsSpec> aerodynamics;
	std::optional<FrictionSpec> friction;
	std::optional<SelfCollisionSpec> selfCollision;
	std::optional<PinSpec> pin;
	std::optional<BodyMotionSpec> bodyMotion;

	/// Names of the listed effects in canonical order.
	std::vector<std::string> listed() const;
};

struct RenderSpec
{
	int width = 1200;
	int height = 900;
	bool showEllipsoids = false; ///< draw the ellipsoids instead of the body mesh
};

struct Scene
{
	std::string path;        ///< the scene file
	std::string name;
	BodySpec body;
	ColliderSpec collider;
	GarmentSpec garment;
	MaterialSpec material;
	SolverSpec solver;
	EffectsSpec effects;
	RenderSpec render;
	int frameEvery = 10;     ///< --frames writes one OBJ every this many steps
	int sampleEvery = 10;    ///< inside-body metric sampled every this many steps (and at the end)
};

/// Reads and validates a scene file (a regular file of at most kMaxJsonFileBytes, nesting at most kMaxJsonDepth
/// levels; input_files.h). \throws FormatError naming the file and the key.
Scene loadScene(const std::string& path);

/// Parses (comments allowed) and validates scene text, with the depth check of loadScene; `path` as in parseScene.
Scene parseSceneText(const std::string& text, const std::string& path);

/// Validates an already-parsed document; `path` names the file in messages and anchors relative paths.
Scene parseScene(const nlohmann::json& document, const std::string& path);

} // namespace bodyfit::drape
