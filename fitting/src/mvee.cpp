// Minimum-volume enclosing ellipsoid: Khachiyan's barycentric coordinate ascent with Todd-Yildirim away/drop steps
// and Kumar-Yildirim initialisation (Todd & Yildirim, "On Khachiyan's algorithm for the computation of minimum-volume
// enclosing ellipsoids", Discrete Appl. Math. 2007), run on an active set with Sherman-Morrison updates, followed
// by an exact rescale over all points in world coordinates.
//
// Notation (d = dimension, l = d + 1): lifted points q_i = (y_i, 1); weights u (sum 1); X(u) = sum_i u_i q_i q_i^T;
// M_i = q_i^T X^-1 q_i. Optimality: max_i M_i = l. With c = sum u_i y_i and S = sum u_i y_i y_i^T - c c^T,
// M_i = 1 + (y_i - c)^T S^-1 (y_i - c) and the ellipsoid is {y : (y - c)^T S^-1 (y - c) <= d}.
#include "bodyfit/fitting/mvee.h"

#include "bodyfit/fitting/errors.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>

namespace bodyfit
{

namespace
{

/// A width below this fraction of the point set's extent counts as zero (collinear / coplanar / duplicate).
/// 1e-10 is far above rounding (~1e-16 of the coordinates) and far below any physical thickness we fit.
constexpr double kRelativeFlatness = 1e-10;
/// Rebuild X^-1 and diag(M) from the weights every this many rank-one updates (bounds the drift of the updates).
constexpr int kRebuildInterval = 64;
/// Violators added to the active set per round (the worst ones).
constexpr int kViolatorsPerRound = 24;
/// Relative growth added to every rescale so that rounding cannot leave max zeta a few ulps above 1.
constexpr double kRescaleGuard = 8.0 * std::numeric_limits<double>::epsilon();

// ---- Active-set Khachiyan solver in d = 2 or 3 dimensions, on well-scaled coordinates -------------------------------

template <int D>
class ActiveSetKhachiyan
{
public:
	static constexpr int L = D + 1;
	using VecD = Eigen::Matrix<double, D, 1>;
	using MatD = Eigen::Matrix<double, D, D>;
	using VecL = Eigen::Matrix<double, L, 1>;
	using MatL = Eigen::Matrix<double, L, L>;
	using Points = Eigen::Matrix<double, D, Eigen::Dynamic>;

	ActiveSetKhachiyan(const Points& y, double tolerance, int maxIterations)
		: y_(y), tolerance_(tolerance), maxIterations_(maxIterations), inActive_(size_t(y.cols()), 0)
	{
	}

	/// `weighted`: initial points sharing the weight uniformly (must affinely span R^D); `extra`: candidates with
	/// weight 0. Returns Ok, NotConverged or NumericalIssue.
	FitStatus solve(const std::vector<int>& weighted, const std::vector<int>& extra)
	{
		for (int i : weighted)
			add(i, 1.0 / double(weighted.size()));
		for (int i : extra)
			add(i, 0.0);
		if (!rebuild())
			return FitStatus::NumericalIssue;

		const int n = int(y_.cols());
		// Each round adds at least one point, so n rounds always suffice; iterations are capped separately.
		for (int round = 0; round <= n; ++round)
		{
			const FitStatus inner = iterate();
			if (inner == FitStatus::NumericalIssue || !rebuild())
				return FitStatus::NumericalIssue;
			extractShape();
			const int added = addViolators();
			if (added < 0)
				return FitStatus::NumericalIssue;
			if (added == 0)
				return inner; // Ok, or NotConverged if the last inner loop hit the cap
			if (iterations_ >= maxIterations_)
				return FitStatus::NotConverged;
		}
		return FitStatus::NotConverged;
	}

	const VecD& center() const { return center_; }
	/// S^-1: the solution ellipsoid (before the final rescale) is (y - c)^T S^-1 (y - c) <= D.
	const MatD& inverseScatter() const { return inverseScatter_; }
	int iterations() const { return iterations_; }
	int activeSize() const { return int(index_.size()); }
	std::vector<int> coreIndices() const
	{
		std::vector<int> core;
		for (size_t a = 0; a < index_.size(); ++a)
			if (u_[a] > 0.0)
				core.push_back(index_[a]);
		std::sort(core.begin(), core.end());
		return core;
	}

private:
	void add(int i, double weight)
	{
		inActive_[size_t(i)] = 1;
		index_.push_back(i);
		VecL q;
		q << y_.col(i), 1.0;
		q_.push_back(q);
		u_.push_back(weight);
		M_.push_back(q.dot(Xinv_ * q)); // refreshed by rebuild() when X^-1 is not yet valid
	}

	/// X from the weights, its inverse, and diag(M) for the active set; false if anything is not finite.
	bool rebuild()
	{
		double sum = 0.0;
		for (double w : u_)
			sum += w;
		if (!(sum > 0.0) || !std::isfinite(sum))
			return false;
		MatL X = MatL::Zero();
		for (size_t a = 0; a < q_.size(); ++a)
		{
			u_[a] /= sum;
			if (u_[a] > 0.0)
				X.noalias() += u_[a] * q_[a] * q_[a].transpose();
		}
		Xinv_ = X.inverse();
		if (!Xinv_.allFinite())
			return false;
		for (size_t a = 0; a < q_.size(); ++a)
			M_[a] = q_[a].dot(Xinv_ * q_[a]);
		return true;
	}

	/// The largest M over the active set (Frank-Wolfe / increase step) and the smallest among weighted points (away /
	/// drop step), each at its first index.
	struct Extremes
	{
		size_t j = 0, k = 0;
		double mMax = -1.0, mMin = std::numeric_limits<double>::infinity();

		void see(size_t a, double m, double u)
		{
			if (m > mMax)
			{
				mMax = m;
				j = a;
			}
			if (u > 0.0 && m < mMin)
			{
				mMin = m;
				k = a;
			}
		}
	};

	Extremes extremes() const
	{
		Extremes e;
		for (size_t a = 0; a < M_.size(); ++a)
			e.see(a, M_[a], u_[a]);
		return e;
	}

	/// The rank-one step on `target` (Sherman-Morrison: X' = (1 - tau)(X + beta q q^T), beta = tau / (1 - tau)):
	/// X^-1, diag(M) and the weights, in one pass that also finds the extremes of the new M (the next step's search).
	Extremes step(size_t target, double tau, bool drop)
	{
		const double beta = tau / (1.0 - tau);
		const double coef = beta / (1.0 + beta * M_[target]);
		const double inv = 1.0 / (1.0 - tau);
		const VecL w = Xinv_ * q_[target];
		Xinv_ = (Xinv_ - coef * w * w.transpose()) * inv;
		Extremes e;
		for (size_t a = 0; a < q_.size(); ++a)
		{
			const double g = w.dot(q_[a]);
			M_[a] = (M_[a] - coef * g * g) * inv;
			u_[a] *= 1.0 - tau;
			if (a == target)
				u_[a] = drop ? 0.0 : u_[a] + tau;
			e.see(a, M_[a], u_[a]);
		}
		return e;
	}

	/// Khachiyan / Todd-Yildirim iterations on the active set until max M <= (1 + tol) l or the cap.
	FitStatus iterate()
	{
		const double l = double(L);
		int sinceRebuild = 0;
		Extremes e = extremes();
		while (true)
		{
			const double mMax = e.mMax, mMin = e.mMin;
			if (!std::isfinite(mMax) || !std::isfinite(mMin))
				return FitStatus::NumericalIssue;
			const double epsPlus = mMax / l - 1.0, epsMinus = 1.0 - mMin / l;
			if (epsPlus <= tolerance_)
				return FitStatus::Ok;
			if (iterations_ >= maxIterations_)
				return FitStatus::NotConverged;

			// Choose the step (Todd-Yildirim): away from k when its deficit exceeds j's excess.
			size_t target = e.j;
			double tau = (mMax - l) / (l * (mMax - 1.0));
			bool drop = false;
			if (epsMinus > epsPlus && u_[e.k] < 1.0)
			{
				const double lower = -u_[e.k] / (1.0 - u_[e.k]);
				double tauAway = mMin - 1.0 > 0.0 ? (mMin - l) / (l * (mMin - 1.0)) : lower;
				bool dropAway = false;
				if (tauAway <= lower)
				{
					tauAway = lower;
					dropAway = true;
				}
				// Removing k's weight must leave X positive definite: 1 + beta M_k > 0 with beta = tau/(1 - tau).
				if (1.0 + tauAway / (1.0 - tauAway) * mMin > 1e-9)
				{
					target = e.k;
					tau = tauAway;
					drop = dropAway;
				}
			}

			e = step(target, tau, drop);
			++iterations_;
			if (++sinceRebuild == kRebuildInterval)
			{
				sinceRebuild = 0;
				if (!rebuild())
					return FitStatus::NumericalIssue;
				e = extremes();
			}
		}
	}

	/// Centre and S^-1 from the (freshly rebuilt) weights: S^-1 is the leading D x D block of X^-1.
	void extractShape()
	{
		center_.setZero();
		for (size_t a = 0; a < q_.size(); ++a)
			center_ += u_[a] * q_[a].template head<D>();
		inverseScatter_ = Xinv_.template topLeftCorner<D, D>();
		inverseScatter_ = 0.5 * (inverseScatter_ + inverseScatter_.transpose()).eval();
	}

	/// O(n) check of every point against (y - c)^T S^-1 (y - c) <= (1 + tol) l - 1; adds the worst violators that
	/// are not active yet. Returns how many were added (-1 if a value was not finite).
	int addViolators()
	{
		const double limit = (1.0 + tolerance_) * double(L) - 1.0;
		candidates_.clear();
		const int n = int(y_.cols());
		for (int i = 0; i < n; ++i)
		{
			const VecD d = y_.col(i) - center_;
			const double m = d.dot(inverseScatter_ * d);
			if (!(m <= limit) && !inActive_[size_t(i)])
				candidates_.emplace_back(m, i);
		}
		for (const auto& c : candidates_)
			if (!std::isfinite(c.first))
				return -1;
		const auto worse = [](const std::pair<double, int>& a, const std::pair<double, int>& b) {
			return a.first > b.first || (a.first == b.first && a.second < b.second);
		};
		if (int(candidates_.size()) > kViolatorsPerRound)
		{
			std::nth_element(candidates_.begin(), candidates_.begin() + kViolatorsPerRound, candidates_.end(), worse);
			candidates_.resize(kViolatorsPerRound);
		}
		std::sort(candidates_.begin(), candidates_.end(), worse);
		for (const auto& c : candidates_)
			add(c.second, 0.0);
		return int(candidates_.size());
	}

	const Points& y_;
	const double tolerance_;
	const int maxIterations_;
	std::vector<char> inActive_;
	std::vector<int> index_;
	std::vector<VecL, Eigen::aligned_allocator<VecL>> q_;
	std::vector<double> u_, M_;
	std::vector<std::pair<double, int>> candidates_;
	MatL Xinv_ = MatL::Identity();
	VecD center_ = VecD::Zero();
	MatD inverseScatter_ = MatD::Identity();
	int iterations_ = 0;
};

// ---- Frame: Kumar-Yildirim directions, rank detection, whitening ----------------------------------------------------

struct Frame
{
	Eigen::Vector3d origin;          ///< mean of the points
	Eigen::Matrix3d axes;            ///< orthonormal columns f1, f2, f3 (det +1)
	Eigen::Vector3d lo, hi;          ///< extent of the centred points along each axis
	int rank = 3;                    ///< 0 (all duplicates), 1 (collinear), 2 (coplanar) or 3
	std::array<int, 6> kyPoints{};   ///< Kumar-Yildirim points: argmax/argmin along the three KY directions
	double flatness = 0.0;           ///< widths <= flatness count as zero
};

/// The input points relative to their mean, read on the fly (no N x 3 copy: the O(N) passes stay allocation-free).
struct Centred
{
	const Eigen::MatrixX3d& points;
	Eigen::Vector3d origin;

	int size() const { return int(points.rows()); }
	Eigen::Vector3d operator()(int i) const
	{
		return Eigen::Vector3d(points(i, 0) - origin[0], points(i, 1) - origin[1], points(i, 2) - origin[2]);
	}
};

/// Index of the largest and smallest value of dir . c_i.
std::pair<int, int> extremes(const Centred& c, const Eigen::Vector3d& dir)
{
	double hi = -std::numeric_limits<double>::infinity(), lo = std::numeric_limits<double>::infinity();
	int hiIdx = 0, loIdx = 0;
	for (int i = 0; i < c.size(); ++i)
	{
		const double p = dir.dot(c(i));
		if (p > hi)
		{
			hi = p;
			hiIdx = i;
		}
		if (p < lo)
		{
			lo = p;
			loIdx = i;
		}
	}
	return {hiIdx, loIdx};
}

/// The centred point farthest from the mean, and its squared distance (0 for none; the first wins a tie).
std::pair<int, double> farthestFromMean(const Centred& c)
{
	int far = 0;
	double extent2 = 0.0;
	for (int i = 0; i < c.size(); ++i)
	{
		const double d2 = c(i).squaredNorm();
		if (d2 > extent2)
		{
			extent2 = d2;
			far = i;
		}
	}
	return {far, extent2};
}

/// The centred point farthest from the line through the mean along the unit vector f1, and its squared distance.
std::pair<int, double> farthestFromLine(const Centred& c, const Eigen::Vector3d& f1)
{
	int farLine = 0;
	double offLine2 = 0.0;
	for (int i = 0; i < c.size(); ++i)
	{
		const Eigen::Vector3d p = c(i);
		const double r2 = (p - f1.dot(p) * f1).squaredNorm();
		if (r2 > offLine2)
		{
			offLine2 = r2;
			farLine = i;
		}
	}
	return {farLine, offLine2};
}

/// In one pass over the points: f.lo and f.hi, the extent along every axis of f.axes, and the KY points along its
/// third axis (a3 at the top, b3 at the bottom; left as they are when every point lies at zero along it).
void frameExtent(const Centred& c, Frame& f, int& a3, int& b3)
{
	const Eigen::Matrix3d Ft = f.axes.transpose();
	f.lo.setConstant(std::numeric_limits<double>::infinity());
	f.hi.setConstant(-std::numeric_limits<double>::infinity());
	for (int i = 0; i < c.size(); ++i)
	{
		const Eigen::Vector3d l = Ft * c(i);
		for (int k = 0; k < 2; ++k)
		{
			f.lo[k] = std::min(f.lo[k], l[k]);
			f.hi[k] = std::max(f.hi[k], l[k]);
		}
		if (l[2] > f.hi[2])
		{
			f.hi[2] = l[2];
			a3 = i;
		}
		if (l[2] < f.lo[2])
		{
			f.lo[2] = l[2];
			b3 = i;
		}
	}
}

/// Builds the KY frame of the centred points: f1 along the first KY difference vector, f2 completing the plane of the
/// first two, f3 their normal (the third KY direction). Detects the affine rank on the way.
Frame buildFrame(const Centred& c, double coordinateMagnitude)
{
	Frame f;
	f.origin = c.origin;
	const auto [far, extent2] = farthestFromMean(c);
	const double extent = std::sqrt(extent2);
	// Rounding of the input coordinates is ~1e-16 of their magnitude: never call anything thinner than that flat.
	f.flatness = std::max(kRelativeFlatness * extent, 64.0 * std::numeric_limits<double>::epsilon() * coordinateMagnitude);
	f.axes.setIdentity();
	f.lo.setZero();
	f.hi.setZero();
	if (!(extent > f.flatness))
	{
		f.rank = 0;
		return f;
	}
	// KY direction 1: towards the farthest point from the mean (so the difference vector is non-zero).
	const auto [a1, b1] = extremes(c, c(far) / extent);
	const Eigen::Vector3d f1 = (c(a1) - c(b1)).normalized();
	// KY direction 2: orthogonal to v1, towards the point farthest from the line through the mean along f1.
	const auto [farLine, offLine2] = farthestFromLine(c, f1);
	const double offLine = std::sqrt(offLine2);
	Eigen::Vector3d f2, f3;
	int a2 = a1, b2 = b1;
	if (offLine > f.flatness)
	{
		const Eigen::Vector3d p = c(farLine);
		std::tie(a2, b2) = extremes(c, (p - f1.dot(p) * f1) / offLine);
		const Eigen::Vector3d v2 = c(a2) - c(b2);
		f2 = (v2 - f1.dot(v2) * f1).normalized();
		f3 = f1.cross(f2).normalized(); // KY direction 3: orthogonal to v1 and v2
	}
	else
	{
		f2 = f1.unitOrthogonal();
		f3 = f1.cross(f2);
	}
	f.axes << f1, f2, f3;
	int a3 = a1, b3 = b1;
	frameExtent(c, f, a3, b3);
	f.kyPoints = {a1, b1, a2, b2, a3, b3};
	const Eigen::Vector3d width = f.hi - f.lo;
	f.rank = width[1] <= f.flatness ? 1 : (width[2] <= f.flatness ? 2 : 3);
	return f;
}

/// Number of distinct points (up to 4) with `tolerance` as the merge distance.
int countDistinct(const Centred& c, double tolerance)
{
	std::vector<Eigen::Vector3d> reps;
	for (int i = 0; i < c.size() && reps.size() < 4; ++i)
	{
		bool seen = false;
		for (const Eigen::Vector3d& r : reps)
			seen = seen || (c(i) - r).norm() <= tolerance;
		if (!seen)
			reps.push_back(c(i));
	}
	return int(reps.size());
}

/// Directions of the extreme points added to the first active set, in whitened coordinates: the axes and the
/// diagonals of the unit cube (D = 3: 7 directions, D = 2: 4). A cheap hull sample that saves active-set rounds.
template <int D>
struct ProbeDirections;
template <>
struct ProbeDirections<3>
{
	static constexpr int kCount = 7;
	static constexpr double kTable[kCount][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1},
	                                             {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
};
template <>
struct ProbeDirections<2>
{
	static constexpr int kCount = 4;
	static constexpr double kTable[kCount][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
};

/// Whitened coordinates along the first D frame axes, y = (f_k . c - mid_k) / width_k, and (same pass) the indices
/// of the extreme points along the probe directions (2 per direction, possibly repeated).
template <int D>
Eigen::Matrix<double, D, Eigen::Dynamic> whiten(const Centred& c, const Frame& f, std::vector<int>& probes)
{
	using Probe = ProbeDirections<D>;
	const Eigen::Matrix<double, D, 1> mid = 0.5 * (f.lo + f.hi).template head<D>();
	const Eigen::Matrix<double, D, 1> invWidth = (f.hi - f.lo).template head<D>().cwiseInverse();
	const Eigen::Matrix<double, D, 3> T = invWidth.asDiagonal() * f.axes.leftCols<D>().transpose();
	std::array<double, Probe::kCount> hi, lo;
	std::array<int, Probe::kCount> hiIdx{}, loIdx{};
	hi.fill(-std::numeric_limits<double>::infinity());
	lo.fill(std::numeric_limits<double>::infinity());
	Eigen::Matrix<double, D, Eigen::Dynamic> y(D, c.size());
	for (int i = 0; i < c.size(); ++i)
	{
		const Eigen::Matrix<double, D, 1> yi = T * c(i) - invWidth.cwiseProduct(mid);
		y.col(i) = yi;
		for (int k = 0; k < Probe::kCount; ++k)
		{
			double p = 0.0;
			for (int j = 0; j < D; ++j)
				p += Probe::kTable[k][j] * yi[j];
			if (p > hi[size_t(k)])
			{
				hi[size_t(k)] = p;
				hiIdx[size_t(k)] = i;
			}
			if (p < lo[size_t(k)])
			{
				lo[size_t(k)] = p;
				loIdx[size_t(k)] = i;
			}
		}
	}
	probes.assign(hiIdx.begin(), hiIdx.end());
	probes.insert(probes.end(), loIdx.begin(), loIdx.end());
	return y;
}

/// Principal axes of a symmetric positive definite D x D shape matrix B = Q diag(lambda) Q^T by cyclic Jacobi rotations
/// (accurate to rounding relative to each eigenvalue's scale, deterministic); semi-axes 1/sqrt(lambda), descending.
template <int D>
bool principalAxes(Eigen::Matrix<double, D, D> B, Eigen::Matrix<double, D, D>& Q, Eigen::Matrix<double, D, 1>& radii)
{
	Q.setIdentity();
	for (int sweep = 0; sweep < 64; ++sweep)
	{
		double off = 0.0;
		for (int p = 0; p < D; ++p)
			for (int q = p + 1; q < D; ++q)
				off = std::max(off, std::abs(B(p, q)) / std::sqrt(std::abs(B(p, p) * B(q, q))));
		if (!(off > 1e-17))
			break;
		for (int p = 0; p < D; ++p)
			for (int q = p + 1; q < D; ++q)
			{
				if (B(p, q) == 0.0)
					continue;
				// Rotation zeroing B(p, q): tan(2 theta) = 2 B_pq / (B_qq - B_pp), smaller root for stability.
				const double theta = (B(q, q) - B(p, p)) / (2.0 * B(p, q));
				const double t = std::copysign(1.0, theta) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
				const double cs = 1.0 / std::sqrt(t * t + 1.0), sn = t * cs;
				Eigen::Matrix<double, D, D> J = Eigen::Matrix<double, D, D>::Identity();
				J(p, p) = cs;
				J(q, q) = cs;
				J(p, q) = sn;
				J(q, p) = -sn;
				B = (J.transpose() * B * J).eval();
				B(p, q) = B(q, p) = 0.0;
				Q = (Q * J).eval();
			}
	}
	Eigen::Matrix<double, D, 1> lambda = B.diagonal();
	// Sort ascending eigenvalues (descending radii); stable on ties for determinism.
	std::array<int, D> order;
	for (int k = 0; k < D; ++k)
		order[size_t(k)] = k;
	std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return lambda[a] < lambda[b]; });
	Eigen::Matrix<double, D, D> sortedQ;
	for (int k = 0; k < D; ++k)
	{
		sortedQ.col(k) = Q.col(order[size_t(k)]);
		radii[k] = 1.0 / std::sqrt(lambda[order[size_t(k)]]);
	}
	Q = sortedQ;
	return lambda.minCoeff() > 0.0 && Q.allFinite() && radii.allFinite();
}

/// Solves in the frame's first D axes and maps the ellipsoid back to world coordinates. Thin axes (k >= D) get
/// radius max(minRadius, 1e3 * half-width) so that the final rescale hardly moves (their offsets are <= 1e-3 r).
template <int D>
FitStatus solveInSubspace(const Centred& c, const Frame& f, const MveeOptions& options,
                          const std::vector<int>& warm, Ellipsoid& out, EllipsoidFit& fit)
{
	std::vector<int> probes;
	const Eigen::Matrix<double, D, Eigen::Dynamic> y = whiten<D>(c, f, probes);
	ActiveSetKhachiyan<D> solver(y, options.tolerance, options.maxIterations);
	std::vector<int> weighted;
	std::vector<char> taken(size_t(c.size()), 0);
	for (int k = 0; k < 2 * D; ++k)
		if (!taken[size_t(f.kyPoints[size_t(k)])]++)
			weighted.push_back(f.kyPoints[size_t(k)]);
	for (int i : warm)
		if (!taken[size_t(i)]++)
			weighted.push_back(i);
	std::vector<int> extra;
	for (int i : probes)
		if (!taken[size_t(i)]++)
			extra.push_back(i);
	const FitStatus status = solver.solve(weighted, extra);
	fit.iterations = solver.iterations();
	fit.activeSetSize = solver.activeSize();
	if (status == FitStatus::NumericalIssue)
		return status;
	fit.coreIndices = solver.coreIndices();

	// World shape: y = W^-1 (F_D^T c - mid) => B = W^-1 (S^-1 / D) W^-1 in the frame axes.
	const Eigen::Matrix<double, D, 1> width = (f.hi - f.lo).template head<D>();
	const Eigen::Matrix<double, D, 1> mid = 0.5 * (f.lo + f.hi).template head<D>();
	const Eigen::Matrix<double, D, D> B =
		width.cwiseInverse().asDiagonal() * (solver.inverseScatter() / double(D)) * width.cwiseInverse().asDiagonal();
	Eigen::Matrix<double, D, D> Q;
	Eigen::Matrix<double, D, 1> r;
	if (!principalAxes<D>(0.5 * (B + B.transpose()), Q, r))
		return FitStatus::NumericalIssue;
	Eigen::Vector3d centerLocal = 0.5 * (f.lo + f.hi);
	centerLocal.head<D>() = mid + width.cwiseProduct(solver.center());
	out.center = f.origin + f.axes * centerLocal;
	Eigen::Matrix3d localRot = Eigen::Matrix3d::Identity();
	localRot.topLeftCorner<D, D>() = Q;
	out.rotation = f.axes * localRot;
	out.radii.head<D>() = r;
	for (int k = D; k < 3; ++k)
		out.radii[k] = std::max(options.minRadius, 1e3 * 0.5 * (f.hi[k] - f.lo[k]));
	return status;
}

/// Rotation with det +1 (flipping an axis does not change the ellipsoid).
void makeProper(Ellipsoid& e)
{
	if (e.rotation.determinant() < 0.0)
		e.rotation.col(0) = -e.rotation.col(0);
}

/// max over all points of Ellipsoid::zeta itself: the rescale below then only changes the final division by the radii,
/// so its rounding guard holds however thin the ellipsoid is (a re-implementation with another operation order can
/// differ by ~1e-16 / (thinnest axis ratio) in zeta, e.g. 1e-10 for a 1e6:1 disc).
double maxZeta(const Eigen::MatrixX3d& points, const Ellipsoid& e)
{
	double z = 0.0;
	for (int i = 0; i < points.rows(); ++i)
		z = std::max(z, e.zeta(Eigen::Vector3d(points(i, 0), points(i, 1), points(i, 2))));
	return z;
}

/// Scales the radii so that max zeta over all points is 1 (to a few ulps: the promise is <= 1 + 1e-9, rounding
/// contributes ~1e-15 even 1 km from the origin). Only the first `scaledAxes` radii take the rescale (the thin axes
/// of a degenerate fit keep minRadius); then a uniform pass fixes what the thin axes' tiny offsets leave over 1.
void rescaleToEnclose(const Eigen::MatrixX3d& points, Ellipsoid& e, int scaledAxes)
{
	const double first = maxZeta(points, e);
	if (!(first > 0.0) || !std::isfinite(first))
		return; // all points at the centre (or a non-finite shape, caught by the caller's validity check)
	e.radii.head(scaledAxes) *= std::sqrt(first) * (1.0 + kRescaleGuard);
	if (scaledAxes == 3)
		return; // uniform scaling: every zeta was divided by first (1 + guard)^2, so max zeta <= 1 up to rounding
	for (int pass = 0; pass < 4; ++pass)
	{
		const double z = maxZeta(points, e);
		if (z <= 1.0 || !std::isfinite(z))
			break;
		e.radii *= std::sqrt(z) * (1.0 + kRescaleGuard);
	}
}

/// Last-resort enclosing ellipsoid: the one circumscribing the frame-aligned bounding box.
Ellipsoid boxEllipsoid(const Frame& f, double minRadius)
{
	Ellipsoid e;
	e.center = f.origin + f.axes * (0.5 * (f.lo + f.hi));
	e.rotation = f.axes;
	e.radii = (0.5 * std::sqrt(3.0) * (f.hi - f.lo)).cwiseMax(minRadius);
	return e;
}

/// The input's problems, each a one-line InvalidInputError: no points, bad options, a non-finite coordinate, a
/// warm-start index out of range or repeated.
void validateMveeInput(const Eigen::MatrixX3d& points, const MveeOptions& options, const std::vector<int>& warmStart)
{
	const int n = int(points.rows());
	if (n == 0)
		throw InvalidInputError("minimumVolumeEllipsoid: the point set is empty");
	if (!(options.minRadius > 0.0) || !std::isfinite(options.minRadius))
		throw InvalidInputError("minimumVolumeEllipsoid: minRadius must be finite and > 0");
	if (!(options.tolerance > 0.0) || !std::isfinite(options.tolerance))
		throw InvalidInputError("minimumVolumeEllipsoid: tolerance must be finite and > 0");
	if (options.maxIterations < 0)
		throw InvalidInputError("minimumVolumeEllipsoid: maxIterations must be >= 0");
	if (!points.allFinite())
	{
		int bad = 0;
		while (bad < n && points.row(bad).allFinite())
			++bad;
		throw InvalidInputError("minimumVolumeEllipsoid: point " + std::to_string(bad) + " has a non-finite coordinate");
	}
	std::vector<char> seen(size_t(n), 0);
	for (int i : warmStart)
	{
		if (i < 0 || i >= n)
			throw InvalidInputError("minimumVolumeEllipsoid: warm-start index " + std::to_string(i) +
			                        " is outside [0, " + std::to_string(n) + ")");
		if (seen[size_t(i)]++)
			throw InvalidInputError("minimumVolumeEllipsoid: warm-start index " + std::to_string(i) +
			                        " is repeated");
	}
}

/// The ellipsoid by the rank of the frame: a point (minRadius ball), a segment (its half-length and thin axes), or
/// Khachiyan's iteration in the plane or in space (the frame's box where it fails numerically). Sets fit.ellipsoid
/// and fit.coreIndices; returns the status before the final rescale.
FitStatus fitByRank(const Centred& c, const Frame& frame, const MveeOptions& options, const std::vector<int>& warmStart,
					EllipsoidFit& fit)
{
	Ellipsoid& e = fit.ellipsoid;
	FitStatus status = FitStatus::Ok;
	if (frame.rank == 0)
	{
		e.center = c.origin;
		e.radii.setConstant(options.minRadius);
		status = FitStatus::TooFewPoints;
		fit.coreIndices = {0};
	}
	else if (frame.rank == 1)
	{
		// Segment: the MVEE degenerates to the segment itself; its half-length is the long semi-axis.
		e.center = c.origin + frame.axes * (0.5 * (frame.lo + frame.hi));
		e.rotation = frame.axes;
		e.radii[0] = 0.5 * (frame.hi[0] - frame.lo[0]);
		for (int k = 1; k < 3; ++k)
			e.radii[k] = std::max(options.minRadius, 1e3 * 0.5 * (frame.hi[k] - frame.lo[k]));
		fit.coreIndices = {std::min(frame.kyPoints[0], frame.kyPoints[1]), std::max(frame.kyPoints[0], frame.kyPoints[1])};
		status = FitStatus::Degenerate;
	}
	else
	{
		status = frame.rank == 2 ? solveInSubspace<2>(c, frame, options, warmStart, e, fit)
		                         : solveInSubspace<3>(c, frame, options, warmStart, e, fit);
		if (status == FitStatus::NumericalIssue)
			e = boxEllipsoid(frame, options.minRadius);
		else if (frame.rank == 2 && status == FitStatus::Ok)
			status = FitStatus::Degenerate;
	}
	if (frame.rank < 3 && countDistinct(c, frame.flatness) < 4)
		status = FitStatus::TooFewPoints;
	return status;
}

/// The exact rescale over all points (world coordinates), then the minimum semi-axis, and a box around the frame if
/// the result is somehow not a valid ellipsoid. Returns the final status.
FitStatus encloseExactly(const Eigen::MatrixX3d& points, const Frame& frame, const MveeOptions& options,
						 FitStatus status, Ellipsoid& e)
{
	rescaleToEnclose(points, e, status == FitStatus::NumericalIssue ? 3 : std::max(frame.rank, 1));
	if ((e.radii.array() < options.minRadius).any())
	{
		e.radii = e.radii.cwiseMax(options.minRadius); // only grows the ellipsoid: enclosure is kept
		if (status == FitStatus::Ok)
			status = FitStatus::Degenerate;
	}
	if (!e.isValid(1e-9))
	{
		// Should not happen (every branch above yields finite radii and an orthonormal frame); keep the promise anyway.
		e = boxEllipsoid(frame, options.minRadius);
		makeProper(e);
		rescaleToEnclose(points, e, 3);
		e.radii = e.radii.cwiseMax(options.minRadius);
		status = FitStatus::NumericalIssue;
	}
	return status;
}

} // namespace

EllipsoidFit minimumVolumeEllipsoid(const Eigen::MatrixX3d& points, const MveeOptions& options)
{
	return minimumVolumeEllipsoid(points, options, std::vector<int>{});
}

EllipsoidFit minimumVolumeEllipsoid(const Eigen::MatrixX3d& points, const MveeOptions& options,
                                    const std::vector<int>& warmStart)
{
	validateMveeInput(points, options, warmStart);
	// Centre on the mean, build the Kumar-Yildirim frame, detect the rank.
	const Eigen::Vector3d origin = points.colwise().mean().transpose();
	const Centred c{points, origin};
	const Frame frame = buildFrame(c, points.cwiseAbs().maxCoeff());
	EllipsoidFit fit;
	const FitStatus status = fitByRank(c, frame, options, warmStart, fit);
	makeProper(fit.ellipsoid);
	fit.status = encloseExactly(points, frame, options, status, fit.ellipsoid);
	return fit;
}

} // namespace bodyfit
