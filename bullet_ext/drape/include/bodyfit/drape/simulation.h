#pragma once
/// \file simulation.h
/// One drape run: the body (mesh + ellipsoids), the Bullet world with the scene's collider, the cloth, the listed
/// effects, stepping with timing, and the cloth-quality metrics of docs/DESIGN.md sec. 5 (computed by bodyfit::metrics,
/// bodyfit/metrics/cloth_metrics.h).

#include "bodyfit/drape/effects.h"
#include "bodyfit/drape/garment.h"
#include "bodyfit/drape/scene.h"

#include "bodyfit/bridge/btSkinnedBodyDriver.h"
#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/rig.h"
#include "bodyfit/fitting/skinned_fit.h"
#include "bodyfit/fitting/types.h"
#include "bodyfit/bullet_ext/btFloatRange.h"
#include "bodyfit/metrics/cloth_metrics.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

class btSoftBody;
class btRigidBody;
class btEllipsoidClothCollider;

namespace bodyfit::drape
{

/// An animated body as loaded (scene body.animation): the rig, its bind-pose fit, the bindings and the clip.
struct AnimatedBodyData
{
	std::shared_ptr<const Rig> rig;
	BodyFit fit;                                ///< the bind-pose fit (read from the fit file or fitted at load)
	std::shared_ptr<const SkinBinding> binding; ///< the fit file's skinning section, or bindSkin at load
	int clip = 0;                               ///< index into rig->clips
	AnimationTiming timing;
	const AnimationClip& animationClip() const { return rig->clips[std::size_t(clip)]; }
};

/// The body as loaded: the whole repaired mesh (every component; inside tests and pictures use it) and the
/// ellipsoids (empty for mesh-bvh / none scenes without a fit), both in the body frame (= world frame at t = 0).
struct BodyData
{
	TriMesh mesh;
	std::vector<Ellipsoid> ellipsoids;
	std::string meshPath;
	std::string ellipsoidSource; ///< fit file, or "fit(...)" when the fitter ran
	double fitSeconds = 0.0;     ///< time spent segmenting and fitting (0 when read from a file)
	std::vector<std::string> fitWarnings; ///< the fit's warnings (e.g. the non-human fallback), when the fitter ran,
										  ///< and why it ran or why the garment may not fit (see loadBody)
	/// What loading the body mesh found: several meshes joined or props left out of the fit, coordinates coarse in
	/// assimp's float (bodyfit::MeshReport::warnings). In the metrics JSON as "load_warnings".
	std::vector<std::string> loadWarnings;
	/// Set for an animated body: then `mesh` is the rig's bind mesh (repaired, the skinning's vertex order) and
	/// `ellipsoids` the bind-pose fit; the simulation poses both at every substep.
	std::shared_ptr<const AnimatedBodyData> animation;
	/// The skin field of a static body for the tight surface: the fit file's (its side file), or baked at load when
	/// the scene's collider asks for the tight surface and the fit has none (0 for animated bodies and other colliders).
	std::shared_ptr<const SkinField> skinField;
	double skinFieldSeconds = 0.0; ///< time of that bake at load (0 when read from the fit's side file)
};

/// Loads the body as the scene says; the overrides replace scene.body.mesh / scene.body.ellipsoids when not empty.
/// An animated scene loads the rig and its clip; its fit is the scene's (or overriding) fit file, which must carry a
/// skinning section that checkBinding accepts for the rig, or else the bind mesh is fitted (body.fit or the
/// defaults) and bound (bindSkin); a mesh override is refused (the body is the rig's skinned mesh).
/// With a mesh override and no ellipsoid override, the scene's fit file is used only if its recorded source (mesh
/// file name and vertex count) is that mesh; otherwise the mesh is fitted (the scene's "fit" options or the
/// defaults) and the reason is the first of fitWarnings. A mesh garment of a scene whose body was overridden by
/// another mesh adds a warning too (it was placed for the scene's body).
/// \throws MeshLoadError, InvalidInputError, FormatError with a one-line reason.
BodyData loadBody(const Scene& scene, const std::string& meshOverride = "", const std::string& ellipsoidOverride = "");

/// Cost of one step, in wall time and in CPU time of the stepping thread (the robust cost on a busy machine).
struct StepStats
{
	double seconds = 0.0;             ///< wall time of the whole step (effects + Bullet)
	double collisionSeconds = 0.0;    ///< Bullet collision detection (soft contacts are generated there) + our collider
	double colliderSeconds = 0.0;     ///< the ellipsoid collider alone (0 for the other colliders)
	double cpuSeconds = 0.0;          ///< thread CPU time of the whole step
	double collisionCpuSeconds = 0.0; ///< thread CPU time of collisionSeconds' phases
	double colliderCpuSeconds = 0.0;  ///< thread CPU time of the ellipsoid collider alone
	/// Animated body (wall time, every substep of the step): posing + skinning + ellipsoid update, and writing the
	/// result into the body's shape (the compound's ellipsoids, or the triangle mesh with its tree refit and
	/// Bullet's cached triangle prisms and sparse-SDF cells dropped). 0 for a body that does not deform.
	double bodySkinSeconds = 0.0;
	double bodyWriteSeconds = 0.0;
	/// Tight surface on an animated body (btEllipsoidClothStats, every substep of the step): tested nodes decided on
	/// the bind-pose field in a bone's frame, and those the union response decided (joints).
	long long boneFieldNodes = 0;
	long long boneFieldFallbacks = 0;
	long long skinMeshNodes = 0; ///< of the bone-field fallbacks, decided on the skinned mesh of the instant
};

/// Cloth-quality numbers at one instant (inside counts, depth, zeta, NaN nodes).
using ClothSample = metrics::PenetrationCounts;

class DrapeSimulation
{
public:
	/// \throws InvalidInputError when the scene cannot run, among others (float Bullet build) when the body or the
	/// garment lies so far from the origin that float coordinates cannot resolve the finest length of the scene
	/// (checkFloatRange below), unless `refuseFarFromOrigin` is false (the far-origin bench measures past it).
	DrapeSimulation(const Scene& scene, const BodyData& body, bool refuseFarFromOrigin = true);
	~DrapeSimulation();
	DrapeSimulation(const DrapeSimulation&) = delete;
	DrapeSimulation& operator=(const DrapeSimulation&) = delete;

	/// One scene step: `solver.substeps` Bullet steps of dt / substeps, each preceded by the listed effects.
	StepStats step();

	int stepsDone() const { return steps_; }
	double time() const { return time_; }
	int nodeCount() const;
	btSoftBody* cloth() const { return cloth_; }
	const GarmentMesh& garment() const { return garment_; }
	const Scene& scene() const { return scene_; }
	const BodyData& body() const { return body_; }
	const EffectCounters& counters() const { return counters_; }
	/// Per-step effect objects actually constructed, in stepping order (unlisted effects never appear).
	std::vector<std::string> steppedEffects() const;
	/// One line describing the collider and its tuning (voxel size, margins, hardness, skin offset).
	const std::string& colliderDescription() const { return colliderDescription_; }
	/// One-line warnings about the run (e.g. a float build far from the origin); also in the metrics JSON.
	const std::vector<std::string>& warnings() const { return warnings_; }
	btEllipsoidClothCollider* ellipsoidCollider() const { return collider_; }

	/// Current body pose (body frame -> world).
	Eigen::Isometry3d bodyPose() const;
	/// The skinned-body driver of an animated body (null otherwise).
	const btSkinnedBodyDriver* skinnedDriver() const;
	/// Cloth nodes (world), as a mesh with the garment's faces.
	TriMesh clothMesh() const;
	/// Body mesh / ellipsoids at the current pose (world); an animated body's skinned mesh and its ellipsoids now.
	TriMesh bodyMeshWorld() const;
	std::vector<Ellipsoid> ellipsoidsWorld() const;

	/// Inside/NaN counts now (the inside-body test runs in the body frame against the original mesh).
	ClothSample sample() const;
	/// How contacts are counted: the nodes bodyfit's collider flagged in its last substep (ellipsoids collider,
	/// either surface: btEllipsoidClothCollider::getContactFlags), holding a Bullet rigid contact after the last step
	/// (mesh-bvh, convex-hull-compound, ellipsoids-sdf), none for `none`.
	metrics::ContactOptions contactOptions() const;
	/// The union's neighbourhood: nodes within skin offset + 3 mm of the ellipsoid union or inside it (the contact
	/// rule before the collider's flags; metrics JSON nodes_near_union).
	metrics::ContactOptions nearUnionOptions() const;
	/// Nodes counted as touching the body (contactOptions()).
	std::vector<int> contactNodes() const;
	/// Signed distance of each listed node to the body skin (negative inside the body mesh).
	std::vector<double> skinDistances(const std::vector<int>& nodes) const;
	/// Contact nodes and their gap to the skin now (contactOptions(), or the rule given).
	metrics::ContactMetrics contacts() const;
	metrics::ContactMetrics contacts(const metrics::ContactOptions& options) const;
	/// Cloth links crossing the body skin now (both ends outside, the segment through the mesh).
	metrics::EdgeCrossings edgeCrossings() const;
	/// Sparse-SDF cells currently cached by Bullet (0 for the ellipsoid collider, which needs none).
	int sdfCells() const;

private:
	void buildCloth();
	void installCollider(bool refuseFarFromOrigin);
	/// The float-range check of the whole scene (checkFloatRange): refuse (when asked) or record a warning.
	void checkFarFromOrigin(bool refuseFarFromOrigin);
	void buildEffects();
	/// Animated body: the driver writing the body's shape, its per-substep effect first in the effect list.
	void buildSkinnedDriver();

	struct Impl;
	std::unique_ptr<Impl> impl_;
	Scene scene_;
	const BodyData& body_;
	GarmentMesh garment_;
	btSoftBody* cloth_ = nullptr;
	btEllipsoidClothCollider* collider_ = nullptr;
	EffectCounters counters_;
	std::vector<std::unique_ptr<Effect>> effects_;
	std::string colliderDescription_;
	std::vector<std::string> warnings_;
	int steps_ = 0;
	double time_ = 0.0;
};

/// Float precision far from the origin (bodyfit/bullet_ext/btFloatRange.h) for the body mesh, its ellipsoids and
/// the garment: the finest length the scene must resolve is the ellipsoid collider's skin offset or the cloth margin,
/// whichever is smaller (at least 1 mm). Returns the status and, unless OK, a one-line message with the distances.
btFloatRangeStatus checkFloatRange(const Scene& scene, const BodyData& body, const TriMesh& garment,
								   std::string* message);

/// Runs `steps` steps, sampling the inside count every scene.sampleEvery steps and at the end, and returns the
/// metrics JSON: the run (steps, nodes, ms_per_step, collision_ms_per_step, ...), the cloth metrics at the end
/// (metrics::toJson: nodes_inside_body, contact_nodes, mean_contact_gap_m, nan_nodes, ...) and their extremes over
/// the samples (max_nodes_inside_body, max_ellipsoid_penetration_m, min_zeta_over_time, max_nan_nodes).
/// `progress` (may be null) is called after every step with (done, total).
nlohmann::json runAndMeasure(DrapeSimulation& sim, int steps,
							 const std::function<void(int, int, const StepStats&)>& progress = nullptr,
							 const std::function<void(int)>& afterStep = nullptr);

} // namespace bodyfit::drape
