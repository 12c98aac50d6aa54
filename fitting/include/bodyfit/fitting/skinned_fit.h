#pragma once
/// \file skinned_fit.h
/// Fit once, follow every frame: the ellipsoids of a bind-pose fit bound to the bones of a rig (rig.h), and their
/// per-frame update, such that the union contains the whole skinned skin surface at every pose.
///
/// Binding (bindSkin). Every ellipsoid j gets a point set P_j in the bind pose: the vertices of its cluster (the
/// fitter's vertexEllipsoid) and, for every triangle whose corners lie in different clusters, the corners of the
/// triangle's pieces (a barycentric grid whose pieces have edges <= the cover spacing, as the fitter's triangle
/// cover cuts them) that are handed to j: each piece goes to the first corner cluster whose bind ellipsoid contains
/// it, else to the corner cluster that comes closest (smallest max zeta). Every point of P_j is a fixed barycentric
/// combination of at most three mesh vertices, so it moves with the skinned triangle. The bind ellipsoid is the
/// fitted one, scaled about its centre when needed so that it contains P_j (a fit without triangle cover).
///
/// Guarantee. If every ellipsoid contains the skinned positions of its points, the union contains the whole skinned
/// surface: a triangle with all corners in one cluster is inside that ellipsoid (an ellipsoid is convex and the
/// skinned triangle is the convex hull of its skinned corners), and every piece of the other triangles has its
/// corners in one P_j (the skinned piece is the hull of its skinned corners). The update below keeps exactly that.
///
/// Update, per frame (SkinnedBody::update). With the skinning matrices S_i of the frame:
///  - rigid: every point of P_j depends on one bone b only (weight 1): the bind ellipsoid moves with S_b (an
///    affine map sends an ellipsoid to an ellipsoid), enlarged by a relative 1e-9 against rounding.
///  - refit (joint regions, several bones): the affine map A that best maps P_j's bind positions to their skinned
///    positions (least squares; computed from per-bone moments in O(bones), since the skinned points are linear in
///    the S_i), applied to the bind ellipsoid (the MVEE is affine-equivariant: if the cluster moved affinely this is
///    its MVEE), then scaled about its centre by the smallest factor that encloses every skinned point of P_j
///    (exact, one pass over P_j), times 1 + 1e-9. A falls back to S_dominant when P_j is flat in the bind pose.
/// Deterministic; no allocation per frame after the first.

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/rig.h"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace bodyfit
{

enum class EllipsoidMotion
{
	Rigid, ///< one bone moves every point: the ellipsoid moves with it
	Refit, ///< several bones: affine fit + exact enclosing scale every frame
};
const char* toString(EllipsoidMotion motion);

/// What an ellipsoid is bound to (recorded in the fit file).
struct EllipsoidBinding
{
	EllipsoidMotion mode = EllipsoidMotion::Refit;
	std::vector<int> bones; ///< bones with weight on its points, by decreasing summed weight; bones[0] dominates
};

/// The "skinning" section of a fit file: everything the per-frame update needs besides the rig itself, and what
/// checkBinding validates a rig against.
struct SkinBinding
{
	int version = 1;
	std::string mesh;          ///< name of the skinned mesh in the rig file
	int vertices = 0;          ///< bind mesh vertices / faces
	int faces = 0;
	struct BoneRecord
	{
		std::string name;
		int parent = -1;
		bool deforms = false;
		Eigen::Affine3d inverseBind = Eigen::Affine3d::Identity(); ///< meaningful when deforms
	};
	std::vector<BoneRecord> bones;
	double coverSpacing = 0.0;        ///< metres: piece size of the bound triangle pieces
	std::vector<int> vertexEllipsoid; ///< per bind vertex: its cluster (-1: not fitted)
	std::vector<EllipsoidBinding> ellipsoids; ///< one per fitted ellipsoid
	int vertexPoints = 0;             ///< sum over ellipsoids of bound vertex points (a check on load)
	int coverPoints = 0;              ///< sum over ellipsoids of bound piece corners that are not vertices
};

/// Current version of the "skinning" section.
constexpr int kSkinBindingVersion = 1;
/// Smallest cover spacing a file may ask for (metres).
constexpr double kMinCoverSpacing = 1e-4;

/// Binds `fit` (made on rig.bindMesh, with fit.vertexEllipsoid) to the rig. `coverSpacing` in metres; <= 0 takes the
/// fit's own (params.coverSpacing, relative to the height when the thresholds are), or 0.003 H when it had no cover.
/// \throws InvalidInputError when the fit does not belong to the rig's bind mesh.
SkinBinding bindSkin(const Rig& rig, const BodyFit& fit, double coverSpacing = 0.0);

/// Checks that `recorded` (read from `name`) belongs to `rig` and `fit`: same mesh size, bones (names, parents,
/// inverse bind matrices), and the same bindings when recomputed. \throws FormatError "<name>: skinning.<field>: ...".
void checkBinding(const Rig& rig, const BodyFit& fit, const SkinBinding& recorded, const std::string& name);

/// JSON text of the section / its parser (called by ellipsoid_io.cpp for the "skinning" key of a fit file).
/// \throws FormatError "<name>: skinning.<field>: <problem>".
std::string skinBindingJson(const SkinBinding& binding);
std::shared_ptr<const SkinBinding> parseSkinBinding(const std::string& sectionJson, const std::string& name,
													int ellipsoidCount);

/// A point bound to an ellipsoid: sum_k weight[k] * vertex[k] (a vertex: weight {1, 0, 0}).
struct BoundPoint
{
	std::array<int, 3> vertex{};
	std::array<double, 3> weight{};
};

struct SkinnedBodyOptions
{
	/// Refit ellipsoids grow per axis (coordinate ascent after the uniform scale, see SkinnedBody::axisScales) instead
	/// of uniformly: a thin ellipsoid pushed out along its thin axis grows along that axis only. Both are exact.
	bool perAxisGrowth = true;
};

/// The body at one frame: skinned vertices and the ellipsoids that contain them.
class SkinnedBody
{
public:
	/// Keeps a reference to `rig` (it must outlive the body); copies what it needs of `fit` and `binding`.
	/// \throws InvalidInputError when binding and rig / fit disagree in size.
	SkinnedBody(const Rig& rig, const BodyFit& fit, const SkinBinding& binding, const SkinnedBodyOptions& options = {});

	/// Poses the rig at time t of `clip` and updates (poseBones + skinningMatrices + update).
	/// \throws InvalidInputError for a NaN time (poseBones; the body keeps its pose).
	void pose(const AnimationClip& clip, double t);
	/// Skins the vertices with `skinning` (skinningMatrices) and updates every ellipsoid.
	void update(const std::vector<Eigen::Affine3d>& skinning);

	const std::vector<Ellipsoid>& ellipsoids() const { return current_; }
	const Eigen::MatrixX3d& vertices() const { return skinned_; }
	const Rig& rig() const { return *rig_; }
	/// Bound points of ellipsoid j (its cluster's vertices first, then piece corners).
	const std::vector<BoundPoint>& points(int j) const { return bound_[std::size_t(j)].points; }
	EllipsoidMotion mode(int j) const { return bound_[std::size_t(j)].mode; }
	/// The bone of ellipsoid j's largest weight (a rigid ellipsoid moves with its skinning matrix).
	int dominantBone(int j) const { return bound_[std::size_t(j)].dominant; }
	/// The bones with weight on ellipsoid j's bound points, and its bind-pose ellipsoid (which contains them).
	const std::vector<int>& bones(int j) const { return bound_[std::size_t(j)].bones; }
	const Ellipsoid& bindEllipsoid(int j) const { return bound_[std::size_t(j)].bind; }
	/// The skinning matrices S_i of the last update, one per bone (empty before the first).
	const std::vector<Eigen::Affine3d>& skinning() const { return skinning_; }
	/// Largest per-axis growth factor of the last update's enclosing step for ellipsoid j (1 for rigid ones), and the
	/// largest growth of a semi-axis in metres (how far the surface was pushed out beyond the moved ellipsoid).
	double lastScale(int j) const { return bound_[std::size_t(j)].lastScale; }
	double lastGrowth(int j) const { return bound_[std::size_t(j)].lastGrowth; }

private:
	struct Bound
	{
		EllipsoidMotion mode = EllipsoidMotion::Refit;
		int dominant = 0;
		Ellipsoid bind;
		std::vector<BoundPoint> points;
		std::vector<int> bones;                      ///< bones with weight on the points
		std::vector<Eigen::Matrix4d> moments;        ///< per bone: sum over points of (weighted source) * p~^T
		Eigen::Matrix4d inverseMoment;               ///< (sum p~ p~^T)^-1 of the bind points
		bool affine = false;                         ///< the least-squares map is well posed
		double lastScale = 1.0;
		double lastGrowth = 0.0;
	};
	void updateOne(Bound& b, Ellipsoid& out, const std::vector<Eigen::Affine3d>& skinning);
	Eigen::Affine3d clusterMap(const Bound& b, const std::vector<Eigen::Affine3d>& skinning) const;
	static Eigen::Vector3d axisScales(const std::vector<Eigen::Array3d>& squares, double zmax,
									  std::vector<Eigen::Array3d>& scratch);

	const Rig* rig_;
	SkinnedBodyOptions options_;
	std::vector<Bound> bound_;
	std::vector<Ellipsoid> current_;
	Eigen::MatrixX3d skinned_;
	std::vector<Eigen::Affine3d> skinning_;
	std::vector<Eigen::Vector3d> rows_;             ///< skinned_ row by row
	std::vector<Eigen::Array3d> squares_, extreme_; ///< scratch of updateOne
};

/// Image of an ellipsoid under an affine map with non-singular linear part (an ellipsoid; SVD of A R diag(r)).
Ellipsoid transformEllipsoid(const Ellipsoid& e, const Eigen::Affine3d& map);

} // namespace bodyfit
