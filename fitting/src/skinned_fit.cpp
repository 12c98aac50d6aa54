// Bone bindings of a bind-pose fit and the per-frame ellipsoid update. See skinned_fit.h.
#include "bodyfit/fitting/skinned_fit.h"

#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/triangle_cover.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

namespace bodyfit
{

const char* toString(EllipsoidMotion motion)
{
	return motion == EllipsoidMotion::Rigid ? "rigid" : "refit";
}

namespace
{

constexpr double kInside = 1.0 + 1e-9;   // the MVEE's own enclosure tolerance (mvee.h), as the fitter's cover
constexpr double kMargin = 1.0 + 1e-9;   // relative growth of a moved ellipsoid against rounding
constexpr double kPerAxisAbove = 1.02 * 1.02; // per-axis growth only for uniform growth > 2% (the rest: uniform)

Eigen::Vector3d positionOf(const BoundPoint& p, const Eigen::MatrixX3d& V)
{
	return p.weight[0] * V.row(p.vertex[0]).transpose() + p.weight[1] * V.row(p.vertex[1]).transpose() +
		   p.weight[2] * V.row(p.vertex[2]).transpose();
}

/// One face whose corners lie in different clusters, cut into a barycentric grid of `level` steps per side: each
/// grid triangle (piece) goes to the first corner cluster whose ellipsoid contains it, else to the one it sticks out
/// of least (ties: the lower index). A piece's corners are handed as bound points: a face corner as its vertex (where
/// that vertex belongs to another cluster), a grid point once per cluster.
struct CrossClusterFace
{
	const std::vector<Ellipsoid>& ellipsoids;
	const std::vector<int>& owner;
	std::array<int, 3> v;        ///< the face's vertices
	std::array<int, 3> clusters; ///< its corners' clusters
	Eigen::Vector3d a, b, d;     ///< its corners' positions
	int level;
	std::vector<char> added; ///< per (corner slot of the cluster, i, j): already handed

	using Piece = std::array<std::array<int, 2>, 3>;

	/// Grid point (i, j): weights i / level, j / level and the rest on the face's corners 0, 1, 2.
	Eigen::Vector3d at(int i, int j) const
	{
		return (double(i) * a + double(j) * b + double(level - i - j) * d) / double(level);
	}

	/// True the first time grid point (i, j) is handed to cluster `id` (one of the corner clusters) in this face.
	bool firstHandout(int id, int i, int j)
	{
		const std::size_t side = std::size_t(level + 1);
		const std::size_t slot = id == clusters[0] ? 0 : id == clusters[1] ? 1 : 2;
		char& seen = added[(slot * side + std::size_t(i)) * side + std::size_t(j)];
		const bool first = seen == 0;
		seen = 1;
		return first;
	}

	/// The corner cluster a piece goes to.
	int owningCluster(const Piece& piece) const
	{
		int best = -1;
		double bestZeta = 0.0;
		for (int id : clusters)
		{
			const Ellipsoid& e = ellipsoids[std::size_t(id)];
			double z = 0.0;
			for (const auto& ij : piece)
				z = std::max(z, e.zeta(at(ij[0], ij[1])));
			if (z <= kInside) // the first corner cluster that contains the piece
				return id;
			if (best < 0 || z < bestZeta || (z == bestZeta && id < best))
			{
				best = id;
				bestZeta = z;
			}
		}
		return best;
	}

	/// Hands the piece's corners to its cluster: face corners into extraVertices, grid points into grid.
	void hand(const Piece& piece, std::vector<std::set<int>>& extraVertices, std::vector<std::vector<BoundPoint>>& grid)
	{
		const int best = owningCluster(piece);
		for (const auto& ij : piece)
		{
			const int i = ij[0], j = ij[1], rest = level - i - j;
			const int corner = i == level ? 0 : j == level ? 1 : rest == level ? 2 : -1;
			if (corner >= 0)
			{
				const int vertex = v[std::size_t(corner)];
				if (owner[std::size_t(vertex)] != best)
					extraVertices[std::size_t(best)].insert(vertex);
			}
			else if (firstHandout(best, i, j))
				grid[std::size_t(best)].push_back(
					{v, {double(i) / double(level), double(j) / double(level), double(rest) / double(level)}});
		}
	}

	/// Every piece of the face, row by row.
	void handAll(std::vector<std::set<int>>& extraVertices, std::vector<std::vector<BoundPoint>>& grid)
	{
		const std::size_t side = std::size_t(level + 1);
		added.assign(3 * side * side, 0);
		for (int i = 0; i < level; ++i)
			for (int j = 0; i + j < level; ++j)
			{
				hand({{{i, j}, {i + 1, j}, {i, j + 1}}}, extraVertices, grid);
				if (i + j + 2 <= level)
					hand({{{i + 1, j}, {i + 1, j + 1}, {i, j + 1}}}, extraVertices, grid);
			}
	}
};

/// Bound point sets P_j in the bind pose (skinned_fit.h): cluster vertices, then the corners of the cross-cluster
/// triangle pieces handed to j (vertices not in j, then grid points inside triangles and on edges).
std::vector<std::vector<BoundPoint>> bindPoints(const TriMesh& mesh, const std::vector<Ellipsoid>& ellipsoids,
												const std::vector<int>& owner, double spacing)
{
	const std::size_t k = ellipsoids.size();
	std::vector<std::vector<BoundPoint>> points(k);
	for (int v = 0; v < mesh.vertexCount(); ++v)
		if (owner[std::size_t(v)] >= 0)
			points[std::size_t(owner[std::size_t(v)])].push_back({{v, v, v}, {1.0, 0.0, 0.0}});
	std::vector<std::set<int>> extraVertices(k);
	std::vector<std::vector<BoundPoint>> grid(k);
	CrossClusterFace face{ellipsoids, owner, {}, {}, {}, {}, {}, 0, {}};
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		face.v = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
		face.clusters = {};
		if (!crossesClusters(mesh, owner, f, face.clusters))
			continue;
		face.a = mesh.V.row(face.v[0]), face.b = mesh.V.row(face.v[1]), face.d = mesh.V.row(face.v[2]);
		face.level = coverCutLevel(face.a, face.b, face.d, spacing);
		face.handAll(extraVertices, grid);
	}
	for (std::size_t j = 0; j < k; ++j)
	{
		for (int vertex : extraVertices[j])
			points[j].push_back({{vertex, vertex, vertex}, {1.0, 0.0, 0.0}});
		points[j].insert(points[j].end(), grid[j].begin(), grid[j].end());
	}
	return points;
}

/// Summed skin weight of every bone over a point set (a point's weight of bone i: sum_k b_k w_{v_k, i}).
std::map<int, double> boneTotals(const Rig& rig, const std::vector<BoundPoint>& points)
{
	std::map<int, double> total;
	for (const BoundPoint& p : points)
		for (int k = 0; k < 3; ++k)
		{
			if (p.weight[std::size_t(k)] == 0.0)
				continue;
			const int v = p.vertex[std::size_t(k)];
			for (int w = rig.weightStart[std::size_t(v)]; w < rig.weightStart[std::size_t(v) + 1]; ++w)
				total[rig.weightBone[std::size_t(w)]] += p.weight[std::size_t(k)] * rig.weight[std::size_t(w)];
		}
	return total;
}

/// Rigid: every source vertex of every point has exactly one influence, and it is the same bone.
bool movesRigidly(const Rig& rig, const std::vector<BoundPoint>& points, int bone)
{
	for (const BoundPoint& p : points)
		for (int k = 0; k < 3; ++k)
		{
			if (p.weight[std::size_t(k)] == 0.0)
				continue;
			const int v = p.vertex[std::size_t(k)];
			if (rig.influenceCount(v) != 1 || rig.weightBone[std::size_t(rig.weightStart[std::size_t(v)])] != bone)
				return false;
		}
	return true;
}

EllipsoidBinding bindingOf(const Rig& rig, const std::vector<BoundPoint>& points)
{
	EllipsoidBinding b;
	const std::map<int, double> total = boneTotals(rig, points);
	for (const auto& [bone, w] : total)
		b.bones.push_back(bone);
	std::stable_sort(b.bones.begin(), b.bones.end(), [&](int x, int y) { return total.at(x) > total.at(y); });
	b.mode = !b.bones.empty() && movesRigidly(rig, points, b.bones[0]) ? EllipsoidMotion::Rigid : EllipsoidMotion::Refit;
	return b;
}

/// Piece size of the binding in metres, never below kMinCoverSpacing (what a fit file may hold).
double spacingOf(const Rig& rig, const BodyFit& fit, double requested)
{
	if (requested > 0.0)
		return std::max(requested, kMinCoverSpacing);
	const TriMesh& m = rig.bindMesh;
	const double height = fit.source.height > 0.0 ? fit.source.height : m.V.col(1).maxCoeff() - m.V.col(1).minCoeff();
	if (fit.params.coverTriangles && fit.params.coverSpacing > 0.0)
		return std::max(fit.params.coverSpacing * (fit.params.relativeToHeight ? height : 1.0), kMinCoverSpacing);
	return std::max(BodyFitOptions().coverSpacing * height, kMinCoverSpacing); // the fitter's default piece size
}

std::vector<Ellipsoid> ellipsoidsOf(const BodyFit& fit)
{
	std::vector<Ellipsoid> out;
	for (const FittedEllipsoid& f : fit.ellipsoids)
		out.push_back(f.ellipsoid);
	return out;
}

} // namespace

Ellipsoid transformEllipsoid(const Ellipsoid& e, const Eigen::Affine3d& map)
{
	Ellipsoid out;
	out.center = map * e.center;
	const Eigen::Matrix3d L = map.linear();
	const double det = L.determinant();
	const double s = std::cbrt(det);
	if (det > 0.0 && ((L.transpose() * L) - Eigen::Matrix3d::Identity() * (s * s)).cwiseAbs().maxCoeff() <= 1e-12 * s * s)
	{
		// A rotation times a uniform scale (every rigid bone motion): exact, no decomposition.
		out.rotation = (L / s) * e.rotation;
		out.radii = e.radii * s;
		return out;
	}
	// General affine map: the image is {c' + B u : |u| <= 1} with B = L R diag(r); its axes are the eigenvectors of
	// B B^T and its semi-axes the square roots of the eigenvalues (the singular values of B).
	const Eigen::Matrix3d B = L * e.rotation * e.radii.asDiagonal();
	const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(B * B.transpose());
	out.rotation = eig.eigenvectors();
	if (out.rotation.determinant() < 0.0)
		out.rotation.col(2) = -out.rotation.col(2);
	out.radii = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
	return out;
}

SkinBinding bindSkin(const Rig& rig, const BodyFit& fit, double coverSpacing)
{
	if (int(fit.vertexEllipsoid.size()) != rig.bindMesh.vertexCount())
		throw InvalidInputError(rig.path + ": the fit was not made on the rig's bind mesh (" +
								std::to_string(fit.vertexEllipsoid.size()) + " cluster labels for " +
								std::to_string(rig.bindMesh.vertexCount()) + " vertices)");
	SkinBinding b;
	b.mesh = rig.meshName;
	b.vertices = rig.bindMesh.vertexCount();
	b.faces = rig.bindMesh.faceCount();
	for (const Bone& bone : rig.bones)
		b.bones.push_back({bone.name, bone.parent, bone.deforms, bone.inverseBind});
	b.coverSpacing = spacingOf(rig, fit, coverSpacing);
	b.vertexEllipsoid = fit.vertexEllipsoid;
	for (int owner : b.vertexEllipsoid)
		if (owner >= int(fit.ellipsoids.size()))
			throw InvalidInputError(rig.path + ": cluster label " + std::to_string(owner) + " out of range");
	const auto points = bindPoints(rig.bindMesh, ellipsoidsOf(fit), b.vertexEllipsoid, b.coverSpacing);
	for (const std::vector<BoundPoint>& p : points)
	{
		b.ellipsoids.push_back(bindingOf(rig, p));
		for (const BoundPoint& q : p)
			(q.weight[1] == 0.0 && q.weight[2] == 0.0 ? b.vertexPoints : b.coverPoints) += 1;
	}
	return b;
}

SkinnedBody::SkinnedBody(const Rig& rig, const BodyFit& fit, const SkinBinding& binding,
						 const SkinnedBodyOptions& options)
	: rig_(&rig), options_(options)
{
	const std::size_t k = fit.ellipsoids.size();
	if (int(binding.vertexEllipsoid.size()) != rig.bindMesh.vertexCount() || binding.ellipsoids.size() != k ||
		int(binding.bones.size()) != rig.boneCount())
		throw InvalidInputError(rig.path + ": the skin binding does not belong to this rig and fit (sizes differ)");
	if (!(binding.coverSpacing >= kMinCoverSpacing))
		throw InvalidInputError(rig.path + ": the skin binding's cover spacing is below 0.1 mm");
	const auto points = bindPoints(rig.bindMesh, ellipsoidsOf(fit), binding.vertexEllipsoid, binding.coverSpacing);
	bound_.resize(k);
	current_.resize(k);
	for (std::size_t j = 0; j < k; ++j)
	{
		Bound& b = bound_[j];
		b.points = points[j];
		// Mode and dominant bone from the rig's weights (what checkBinding compares the file's record with), so
		// that containment never rests on an unchecked record.
		const EllipsoidBinding own = bindingOf(rig, b.points);
		b.mode = own.mode;
		b.dominant = own.bones.empty() ? 0 : own.bones[0];
		b.bind = fit.ellipsoids[j].ellipsoid;
		// Bind ellipsoid: contains every bound point (scaled about its centre when a piece was not inside).
		double zmax = 0.0;
		for (const BoundPoint& p : b.points)
			zmax = std::max(zmax, b.bind.zeta(positionOf(p, rig.bindMesh.V)));
		if (zmax > 1.0)
			b.bind.radii *= std::sqrt(zmax);
		// Moments of the least-squares affine map (skinned_fit.h): M = sum p~ p~^T, and per bone
		// Q_i = sum_p (sum_k b_k w_{v_k,i} v~_k) p~^T, so that sum_p p' p~^T = sum_i S_i Q_i.
		Eigen::Matrix4d M = Eigen::Matrix4d::Zero();
		std::map<int, Eigen::Matrix4d> Q;
		for (const BoundPoint& p : b.points)
		{
			Eigen::Vector4d pt;
			pt << positionOf(p, rig.bindMesh.V), 1.0;
			M += pt * pt.transpose();
			for (int c = 0; c < 3; ++c)
			{
				const double bc = p.weight[std::size_t(c)];
				const int v = p.vertex[std::size_t(c)];
				if (bc == 0.0)
					continue;
				Eigen::Vector4d vt;
				vt << rig.bindMesh.V.row(v).transpose(), 1.0;
				for (int w = rig.weightStart[std::size_t(v)]; w < rig.weightStart[std::size_t(v) + 1]; ++w)
				{
					auto it = Q.emplace(rig.weightBone[std::size_t(w)], Eigen::Matrix4d::Zero()).first;
					it->second += (bc * rig.weight[std::size_t(w)]) * vt * pt.transpose();
				}
			}
		}
		b.bones.clear();
		for (const auto& [bone, q] : Q)
		{
			b.bones.push_back(bone);
			b.moments.push_back(q);
		}
		// Well posed when the bind points span 3-D (centred covariance not flat: axis ratio > 1e-3).
		const double n = M(3, 3);
		const Eigen::Vector3d mean = M.block<3, 1>(0, 3) / n;
		const Eigen::Matrix3d cov = M.block<3, 3>(0, 0) / n - mean * mean.transpose();
		const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov, Eigen::EigenvaluesOnly);
		b.affine = b.points.size() >= 4 && eig.eigenvalues()(0) > 1e-6 * eig.eigenvalues()(2);
		if (b.affine)
			b.inverseMoment = M.inverse();
		current_[j] = b.bind;
	}
	skinned_ = rig.bindMesh.V;
}

void SkinnedBody::pose(const AnimationClip& clip, double t)
{
	update(skinningMatrices(*rig_, poseBones(*rig_, clip, t)));
}

void SkinnedBody::update(const std::vector<Eigen::Affine3d>& skinning)
{
	skinning_ = skinning;
	skinVertices(*rig_, skinning, skinned_);
	rows_.resize(std::size_t(skinned_.rows())); // row-major copy: the point pass reads whole vertices
	for (Eigen::Index v = 0; v < skinned_.rows(); ++v)
		rows_[std::size_t(v)] = skinned_.row(v).transpose();
	for (std::size_t j = 0; j < bound_.size(); ++j)
		updateOne(bound_[j], current_[j], skinning);
}

Eigen::Affine3d SkinnedBody::clusterMap(const Bound& b, const std::vector<Eigen::Affine3d>& skinning) const
{
	const Eigen::Affine3d& dominant = skinning[std::size_t(b.dominant)];
	if (!b.affine)
		return dominant;
	Eigen::Matrix<double, 3, 4> N = Eigen::Matrix<double, 3, 4>::Zero();
	for (std::size_t i = 0; i < b.bones.size(); ++i)
		N.noalias() += skinning[std::size_t(b.bones[i])].affine() * b.moments[i];
	Eigen::Affine3d fitted;
	fitted.matrix().topRows<3>() = N * b.inverseMoment;
	fitted.matrix().row(3) << 0.0, 0.0, 0.0, 1.0;
	// Keep the least-squares map unless it collapses or inverts the cluster (volume ratio to the dominant bone's
	// motion outside [0.1, 10]): then the dominant bone's motion is the better start.
	const double ratio = fitted.linear().determinant() / dominant.linear().determinant();
	return fitted.matrix().allFinite() && ratio > 0.1 && ratio < 10.0 ? fitted : dominant;
}

void SkinnedBody::updateOne(Bound& b, Ellipsoid& out, const std::vector<Eigen::Affine3d>& skinning)
{
	if (b.mode == EllipsoidMotion::Rigid)
	{
		out = transformEllipsoid(b.bind, skinning[std::size_t(b.dominant)]);
		// (A bone scaled to 0, as rigs hide parts, maps the ellipsoid onto a point or a disc as it maps the skin:
		// the joint update's smallest radius keeps it a valid ellipsoid around that collapsed skin.)
		out.radii = (out.radii * kMargin).cwiseMax(1e-6);
		b.lastScale = 1.0;
		b.lastGrowth = 0.0;
		return;
	}
	out = transformEllipsoid(b.bind, clusterMap(b, skinning));
	out.radii = out.radii.cwiseMax(1e-9); // a collapsing map: the scaling below restores the size
	// The skinned points in the moved ellipsoid's unit frame, squared per axis: a point is inside the ellipsoid with
	// radii r_k / sqrt(t_k) iff sum_k t_k u_k^2 <= 1.
	const Eigen::Matrix3d W = out.radii.cwiseInverse().asDiagonal() * out.rotation.transpose();
	const Eigen::Vector3d c = out.center;
	squares_.resize(b.points.size());
	double zmax = 0.0;
	for (std::size_t i = 0; i < b.points.size(); ++i)
	{
		const BoundPoint& p = b.points[i];
		const Eigen::Vector3d q = p.weight[0] * rows_[std::size_t(p.vertex[0])] +
								  p.weight[1] * rows_[std::size_t(p.vertex[1])] + p.weight[2] * rows_[std::size_t(p.vertex[2])];
		squares_[i] = (W * (q - c)).array().square();
		zmax = std::max(zmax, squares_[i].sum());
	}
	const Eigen::Vector3d t = options_.perAxisGrowth ? axisScales(squares_, zmax, extreme_)
													 : Eigen::Vector3d::Constant(zmax > 0.0 ? 1.0 / zmax : 1.0);
	const Eigen::Vector3d growth = t.cwiseSqrt().cwiseInverse() * kMargin;
	b.lastScale = growth.maxCoeff();
	b.lastGrowth = (out.radii.cwiseProduct(growth) - out.radii).maxCoeff();
	out.radii = out.radii.cwiseProduct(growth).cwiseMax(1e-6);
}

Eigen::Vector3d SkinnedBody::axisScales(const std::vector<Eigen::Array3d>& u2, double zmax,
										std::vector<Eigen::Array3d>& extreme_)
{
	// The ellipsoid with radii r_k / sqrt(t_k) contains point i iff t . a_i <= 1 (a_i = u_i^2). Smallest volume =
	// max sum_k log t_k under those constraints, a 3-variable problem whose dual is a design p on the points with
	// t_k = 1 / (3 sum_i p_i a_ik) (as for the MVEE, restricted to the ellipsoid's own axes). A few Frank-Wolfe
	// (Khachiyan) steps on the extreme points (largest a_ik per axis, largest sum) give t; a last pass over every
	// point rescales t uniformly so that all are inside: exact whatever the iterations reached.
	const Eigen::Vector3d uniform = Eigen::Vector3d::Constant(zmax > 0.0 ? 1.0 / zmax : 1.0);
	if (!(zmax > kPerAxisAbove))
		return uniform;
	Eigen::Array3d top = Eigen::Array3d::Zero();
	for (const Eigen::Array3d& a : u2)
		top = top.max(a);
	extreme_.clear();
	for (const Eigen::Array3d& a : u2)
		if ((a >= 0.8 * top).any() || a.sum() >= 0.8 * zmax)
			extreme_.push_back(a);
	std::vector<double> p(extreme_.size(), 1.0 / double(extreme_.size()));
	Eigen::Array3d M = Eigen::Array3d::Zero();
	for (std::size_t i = 0; i < extreme_.size(); ++i)
		M += p[i] * extreme_[i];
	for (int iteration = 0; iteration < 20; ++iteration)
	{
		const Eigen::Array3d inv = M.max(1e-12 * top).inverse();
		std::size_t best = 0;
		double g = -1.0;
		for (std::size_t i = 0; i < extreme_.size(); ++i)
		{
			const double gi = (extreme_[i] * inv).sum();
			if (gi > g)
			{
				g = gi;
				best = i;
			}
		}
		if (g <= 3.0 * (1.0 + 1e-3)) // within 0.1% of the optimum's condition max g = 3
			break;
		const double beta = (g - 3.0) / (3.0 * (g - 1.0));
		for (double& pi : p)
			pi *= 1.0 - beta;
		p[best] += beta;
		M = (1.0 - beta) * M + beta * extreme_[best];
	}
	Eigen::Vector3d t = (3.0 * M.max(1e-12 * top)).inverse().matrix();
	double worst = 0.0;
	for (const Eigen::Array3d& a : u2)
		worst = std::max(worst, t[0] * a[0] + t[1] * a[1] + t[2] * a[2]);
	t /= worst;
	// Keep whichever of the two encloses less volume (prod t_k^-1/2).
	return t.prod() > uniform.prod() ? t : uniform;
}

} // namespace bodyfit
