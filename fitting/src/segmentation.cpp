/// \file segmentation.cpp
/// Semantic segmentation of a standing human body (paper sec. 2; docs/DESIGN.md sec. 2).

#include "bodyfit/fitting/segmentation.h"

#include "bodyfit/fitting/components.h"
#include "bodyfit/fitting/mesh_io.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <tuple>

namespace bodyfit
{

namespace
{

constexpr const char* kRegionNames[] = {
	"head",
	"torso.lower.left",
	"torso.lower.right",
	"torso.middle.left",
	"torso.middle.right",
	"torso.upper.left",
	"torso.upper.right",
	"arm.upper.left",
	"arm.upper.right",
	"arm.lower.left",
	"arm.lower.right",
	"leg.upper.left",
	"leg.upper.right",
	"leg.lower.left",
	"leg.lower.right",
	"whole",
};
constexpr int kRegionNameCount = int(sizeof(kRegionNames) / sizeof(kRegionNames[0]));
static_assert(kRegionNameCount == int(Region::Whole) + 1, "one name per Region");

} // namespace

const char* regionName(Region region)
{
	const int index = int(region);
	if (index < 0 || index >= kRegionNameCount)
		return "unknown";
	return kRegionNames[index];
}

bool regionFromName(const std::string& name, Region* region)
{
	for (int i = 0; i < kRegionNameCount; ++i)
	{
		if (name == kRegionNames[i])
		{
			if (region)
				*region = Region(i);
			return true;
		}
	}
	return false;
}

bool isTorso(Region region)
{
	return region >= Region::TorsoLowerLeft && region <= Region::TorsoUpperRight;
}

namespace
{

using Clock = std::chrono::steady_clock;

/// One Dijkstra field with its shortest-path tree.
struct Field
{
	std::vector<double> d;
	std::vector<int> pred;
};

Eigen::Vector3d vertex(const TriMesh& mesh, int v) { return mesh.V.row(v).transpose(); }

/// "1.23%" (two significant decimals).
std::string percent(double share)
{
	char buf[32];
	std::snprintf(buf, sizeof buf, "%.2f%%", 100.0 * share);
	return buf;
}

/// A third of the area of every face touching a vertex (the barycentric vertex area).
std::vector<double> vertexAreas(const TriMesh& mesh)
{
	std::vector<double> area(size_t(mesh.vertexCount()), 0.0);
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		const Eigen::Vector3d a = vertex(mesh, mesh.F(f, 0)), b = vertex(mesh, mesh.F(f, 1)),
							  c = vertex(mesh, mesh.F(f, 2));
		const double third = (b - a).cross(c - a).norm() / 6.0;
		for (int k = 0; k < 3; ++k)
			area[size_t(mesh.F(f, k))] += third;
	}
	return area;
}

/// Total length of the isolines {d = t} for t = t0 + i step, i in [0, count): the perimeter of the cross-section
/// that a geodesic front cuts through the surface at each level. Levels exactly at a vertex value are skipped by
/// the strict comparisons (measure zero).
std::vector<double> isolineLengths(const TriMesh& mesh, const std::vector<double>& d, double t0, double step,
	int count)
{
	std::vector<double> length(size_t(std::max(count, 0)), 0.0);
	if (count <= 0 || !(step > 0.0))
		return length;
	const double t1 = t0 + step * (count - 1);
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		std::array<int, 3> v = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)};
		const double d0 = d[size_t(v[0])], d1 = d[size_t(v[1])], d2 = d[size_t(v[2])];
		if (std::max({d0, d1, d2}) <= t0 || std::min({d0, d1, d2}) >= t1 || !std::isfinite(d0 + d1 + d2))
			continue; // most faces: outside the band
		std::sort(v.begin(), v.end(), [&](int x, int y) { return d[size_t(x)] < d[size_t(y)]; });
		const double lo = d[size_t(v[0])], mid = d[size_t(v[1])], hi = d[size_t(v[2])];
		const int i0 = std::max(0, int(std::ceil((lo - t0) / step)));
		const int i1 = std::min(count - 1, int(std::floor((hi - t0) / step)));
		const Eigen::Vector3d p0 = vertex(mesh, v[0]), p1 = vertex(mesh, v[1]), p2 = vertex(mesh, v[2]);
		for (int i = i0; i <= i1; ++i)
		{
			const double t = t0 + step * i;
			if (!(t > lo && t < hi))
				continue;
			// The level crosses the long edge (lo, hi) and one of the two short ones.
			const Eigen::Vector3d q = p0 + (p2 - p0) * ((t - lo) / (hi - lo));
			Eigen::Vector3d r;
			if (t < mid)
				r = p0 + (p1 - p0) * ((t - lo) / (mid - lo));
			else if (t > mid)
				r = p1 + (p2 - p1) * ((t - mid) / (hi - mid));
			else
				r = p1;
			length[size_t(i)] += (q - r).norm();
		}
	}
	return length;
}

/// The narrowest cross-section near a predicted cut: among the interior local minima of the isoline length over
/// [center - band, center + band] (3-tap moving average, which removes single-level tessellation noise), the level
/// with the shortest isoline; `center` itself when the profile has no interior minimum (a monotone taper, e.g. the
/// forearm towards the wrist, must not drag the cut to the edge of the band).
double narrowestLevel(const TriMesh& mesh, const std::vector<double>& d, double center, double band, double step)
{
	const int count = std::max(5, int(std::ceil(2.0 * band / step)) + 1);
	const double t0 = center - band;
	const std::vector<double> raw = isolineLengths(mesh, d, t0, step, count);
	std::vector<double> smooth(raw.size(), 0.0);
	for (int i = 1; i + 1 < count; ++i)
		smooth[size_t(i)] = (raw[size_t(i - 1)] + raw[size_t(i)] + raw[size_t(i + 1)]) / 3.0;
	int best = -1;
	for (int i = 2; i + 2 < count; ++i)
	{
		const double s = smooth[size_t(i)];
		const bool localMin = s > 0.0 && s <= smooth[size_t(i - 1)] && s <= smooth[size_t(i + 1)] &&
							  (s < smooth[size_t(i - 1)] || s < smooth[size_t(i + 1)]);
		if (localMin && (best < 0 || s < smooth[size_t(best)]))
			best = i;
	}
	return best < 0 ? center : t0 + step * best;
}

/// The vertex of `path` whose value in `d` is closest to `level`.
int pathVertexAt(const std::vector<int>& path, const std::vector<double>& d, double level)
{
	int best = path.empty() ? -1 : path.front();
	double bestGap = std::numeric_limits<double>::infinity();
	for (int v : path)
	{
		const double gap = std::abs(d[size_t(v)] - level);
		if (gap < bestGap)
		{
			bestGap = gap;
			best = v;
		}
	}
	return best;
}

/// Index in `path` of the vertex with the largest distance from the chord path[a] -> path[b] (a < b), or -1.
int deepestOnChord(const TriMesh& mesh, const std::vector<int>& path, int a, int b, double* depth)
{
	*depth = 0.0;
	if (a < 0 || b <= a + 1)
		return -1;
	const Eigen::Vector3d pa = vertex(mesh, path[size_t(a)]), pb = vertex(mesh, path[size_t(b)]);
	const Eigen::Vector3d axis = pb - pa;
	const double axisLength2 = axis.squaredNorm();
	int best = -1;
	for (int i = a + 1; i < b; ++i)
	{
		const Eigen::Vector3d w = vertex(mesh, path[size_t(i)]) - pa;
		const double along = axisLength2 > 0.0 ? std::clamp(w.dot(axis) / axisLength2, 0.0, 1.0) : 0.0;
		const double dist = (w - along * axis).norm();
		if (dist > *depth)
		{
			*depth = dist;
			best = i;
		}
	}
	return best;
}

/// The connected pieces of the regions on the main component (mesh edges between vertices of one label), each with
/// its vertices (in BFS order), label and surface area.
struct LabelPieces
{
	std::vector<int> piece;   ///< per vertex, its piece (-1: not on the main component)
	std::vector<int> members; ///< vertices of every piece, piece by piece
	std::vector<int> begin, size;
	std::vector<double> area;
	std::vector<Region> label;

	int count() const { return int(size.size()); }
	const int* first(int id) const { return members.data() + begin[size_t(id)]; }
	const int* last(int id) const { return first(id) + size[size_t(id)]; }

	void find(const GeodesicSolver& graph, const std::vector<int>& component, const std::vector<double>& vertexArea,
			  const std::vector<Region>& labels)
	{
		const int n = int(labels.size());
		piece.assign(size_t(n), -1);
		members.clear();
		begin.clear();
		size.clear();
		area.clear();
		label.clear();
		for (int s = 0; s < n; ++s)
		{
			if (piece[size_t(s)] >= 0 || component[size_t(s)] != 0)
				continue;
			const int id = count();
			const size_t start = members.size();
			begin.push_back(int(start));
			label.push_back(labels[size_t(s)]);
			piece[size_t(s)] = id;
			members.push_back(s);
			for (size_t i = start; i < members.size(); ++i)
			{
				const auto [nb, ne] = graph.neighbors(members[i]);
				for (const int* w = nb; w != ne; ++w)
					if (graph.isMeshEdge(w) && piece[size_t(*w)] < 0 && labels[size_t(*w)] == labels[size_t(s)])
					{
						piece[size_t(*w)] = id;
						members.push_back(*w);
					}
			}
			size.push_back(int(members.size() - start));
			double a = 0.0;
			for (size_t i = start; i < members.size(); ++i)
				a += vertexArea[size_t(members[i])];
			area.push_back(a);
		}
	}

	/// Per label, its largest piece by area (the first found wins a tie: lowest vertex index); -1 for none.
	std::array<int, kBodyRegionCount + 1> largest() const
	{
		std::array<int, kBodyRegionCount + 1> keep;
		keep.fill(-1);
		for (int id = 0; id < count(); ++id)
		{
			int& k = keep[size_t(label[size_t(id)])];
			if (k < 0 || area[size_t(id)] > area[size_t(k)])
				k = id;
		}
		return keep;
	}

	/// The label most mesh-edge neighbours of piece `id` outside it carry (lowest region index on ties), -1 when it
	/// has none on the main component.
	int majorityAround(int id, const GeodesicSolver& graph, const std::vector<int>& component,
					   const std::vector<Region>& labels) const
	{
		std::array<int, kBodyRegionCount + 1> votes{};
		for (const int* v = first(id); v != last(id); ++v)
		{
			const auto [nb, ne] = graph.neighbors(*v);
			for (const int* w = nb; w != ne; ++w)
				if (graph.isMeshEdge(w) && piece[size_t(*w)] != id && component[size_t(*w)] == 0)
					++votes[size_t(labels[size_t(*w)])];
		}
		const int winner = int(std::max_element(votes.begin(), votes.end()) - votes.begin());
		return votes[size_t(winner)] == 0 ? -1 : winner;
	}
};

/// Re-labels every connected piece of a region except its largest (by surface area, `area` per vertex: the answer
/// does not depend on how finely a part is tessellated) with the label most of its neighbours outside the piece
/// carry, until every region is one piece (or `maxPasses` is reached).
void mergeStrayPieces(const GeodesicSolver& graph, const std::vector<int>& component, const std::vector<double>& area,
	std::vector<Region>& labels, int maxPasses)
{
	LabelPieces pieces;
	for (int pass = 0; pass < maxPasses; ++pass)
	{
		pieces.find(graph, component, area, labels);
		const std::array<int, kBodyRegionCount + 1> keep = pieces.largest();
		bool changed = false;
		for (int id = 0; id < pieces.count(); ++id)
		{
			if (keep[size_t(pieces.label[size_t(id)])] == id)
				continue;
			const int winner = pieces.majorityAround(id, graph, component, labels);
			if (winner < 0)
				continue;
			for (const int* v = pieces.first(id); v != pieces.last(id); ++v)
				labels[size_t(*v)] = Region(winner);
			changed = true;
		}
		if (!changed)
			return;
	}
}

} // namespace

Segmentation wholeBodySegmentation(const TriMesh& mesh, const std::string& reason)
{
	Segmentation result;
	result.ok = false;
	result.failureReason = reason;
	result.labels.assign(size_t(mesh.vertexCount()), Region::Whole);
	if (mesh.vertexCount() > 0)
		result.height = mesh.V.col(1).maxCoeff() - mesh.V.col(1).minCoeff();
	return result;
}

namespace
{

/// Coarse parts before the limbs and the torso are cut into regions.
enum Part
{
	kHead,
	kArmL,
	kArmR,
	kLegL,
	kLegR,
	kTorso
};

/// What the steps of segmentInto share. Each step reads what the earlier ones found and returns a non-empty reason
/// when the mesh does not look like a standing human.
struct SegmentationWork
{
	SegmentationWork(const TriMesh& m, const SegmentationOptions& o, Segmentation& s)
		: mesh(m), options(o), seg(s), n(m.vertexCount())
	{
	}

	const TriMesh& mesh;
	const SegmentationOptions& options;
	Segmentation& seg;
	int n;

	ComponentLayout layout;     ///< components: body, attached, inside, detached (components.h)
	std::vector<int> component; ///< 0 = on the body (its largest component and the parts joined to it), 1 = not
	int componentCount = 0;
	int mainCount = 0;          ///< vertices on the body
	double yMin = 0.0, H = 0.0; ///< floor and height of the body
	std::vector<double> area;   ///< per vertex
	double totalArea = 0.0;     ///< of the main component
	std::optional<GeodesicSolver> solver;
	int center = -1;            ///< main-component vertex nearest the area centroid
	std::array<Field, 5> fields; ///< geodesic field of every extremity, in pick order
	std::array<int, 5> ends{};   ///< the extremities, in pick order
	const Field* head = nullptr;
	const Field* handL = nullptr;
	const Field* handR = nullptr;
	const Field* footL = nullptr;
	const Field* footR = nullptr;
	std::vector<double> neckDepth; ///< along the body axis below the head top (near the head; infinity elsewhere)
	std::vector<char> inHead;
	std::vector<char> part;      ///< Part per vertex
	std::array<double, 6> partArea{};
	int contested = 0;           ///< vertices claimed by more than one part
	double contestedArea = 0.0;  ///< their area

	double y(int v) const { return mesh.V(v, 1); }
	double heightOf(int v) const { return (y(v) - yMin) / H; }
};

/// Components, the body's size and height. The body = the largest component and the separate parts joined to it
/// (bridged: one geodesic graph); enclosed parts (eyes, teeth) and detached ones stay out of the geodesics and take
/// the label of the nearest body vertex (labelOtherComponents).
std::string measureMainComponent(SegmentationWork& w)
{
	w.layout = analyzeComponents(w.mesh, w.options.components);
	w.componentCount = int(w.layout.components.size());
	w.component.assign(size_t(w.n), 0);
	for (int v = 0; v < w.n; ++v)
	{
		w.component[size_t(v)] = w.layout.onBody(v) ? 0 : 1;
		w.mainCount += 1 - w.component[size_t(v)];
	}
	if (w.mainCount < 100)
		return "too few vertices for a body (" + std::to_string(w.mainCount) + " on the body, need 100)";

	double yMin = std::numeric_limits<double>::infinity(), yMax = -yMin;
	for (int v = 0; v < w.n; ++v)
	{
		if (w.component[size_t(v)] != 0)
			continue;
		yMin = std::min(yMin, w.mesh.V(v, 1));
		yMax = std::max(yMax, w.mesh.V(v, 1));
	}
	w.yMin = yMin;
	w.H = yMax - yMin;
	w.seg.height = w.H;
	if (!(w.H > 0.0))
		return "the mesh has no height (flat in y)";
	return {};
}

/// Centre: the vertex of the main component nearest its area-weighted centroid.
std::string findCentre(SegmentationWork& w)
{
	Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
	for (int v = 0; v < w.n; ++v)
	{
		if (w.component[size_t(v)] != 0)
			continue;
		centroid += w.area[size_t(v)] * vertex(w.mesh, v);
		w.totalArea += w.area[size_t(v)];
	}
	if (!(w.totalArea > 0.0))
		return "the mesh has zero surface area";
	centroid /= w.totalArea;
	double bestCenter = std::numeric_limits<double>::infinity();
	for (int v = 0; v < w.n; ++v)
	{
		const double d2 = (vertex(w.mesh, v) - centroid).squaredNorm();
		if (w.component[size_t(v)] == 0 && d2 < bestCenter)
		{
			bestCenter = d2;
			w.center = v;
		}
	}
	return {};
}

/// End feature points: farthest-point sampling in the geodesic metric, seeded with the centre. On a human the
/// five extremities (head top, two fingertips, two toe tips) are each farther from everything chosen before
/// than any other point; the field of every chosen point is kept for the rest of the pipeline.
std::string findExtremities(SegmentationWork& w)
{
	std::vector<double> centerField;
	w.solver->compute(w.center, centerField);
	std::vector<double> nearest = centerField;
	for (int k = 0; k < 5; ++k)
	{
		int far = -1;
		double farDistance = -1.0;
		for (int v = 0; v < w.n; ++v)
		{
			if (std::isfinite(nearest[size_t(v)]) && nearest[size_t(v)] > farDistance)
			{
				farDistance = nearest[size_t(v)];
				far = v;
			}
		}
		if (far < 0 || !(farDistance > 0.0))
			return "fewer than five extremities found";
		w.ends[size_t(k)] = far;
		w.solver->compute(far, w.fields[size_t(k)].d, &w.fields[size_t(k)].pred);
		for (int v = 0; v < w.n; ++v)
			nearest[size_t(v)] = std::min(nearest[size_t(v)], w.fields[size_t(k)].d[size_t(v)]);
	}
	return {};
}

/// Classify: feet = the two lowest, head = the highest of the other three, hands = the remaining two; the subject's
/// left is +x. Then the checks that catch most non-humans early (the remaining ones fail the later checks).
std::string classifyExtremities(SegmentationWork& w)
{
	const TriMesh& mesh = w.mesh;
	const std::array<int, 5>& ends = w.ends;
	std::array<int, 5> order = {0, 1, 2, 3, 4};
	std::sort(order.begin(), order.end(), [&](int a, int b) {
		const Eigen::RowVector3d pa = mesh.V.row(ends[size_t(a)]), pb = mesh.V.row(ends[size_t(b)]);
		return std::make_tuple(pa.y(), pa.x(), pa.z()) < std::make_tuple(pb.y(), pb.x(), pb.z());
	});
	auto byX = [&](int a, int b, int* left, int* right) {
		const bool aLeft = mesh.V(ends[size_t(a)], 0) > mesh.V(ends[size_t(b)], 0);
		*left = aLeft ? a : b;
		*right = aLeft ? b : a;
	};
	int iFootL, iFootR, iHandL, iHandR;
	byX(order[0], order[1], &iFootL, &iFootR);
	byX(order[2], order[3], &iHandL, &iHandR);
	const int iHead = order[4];
	w.head = &w.fields[size_t(iHead)];
	w.handL = &w.fields[size_t(iHandL)];
	w.handR = &w.fields[size_t(iHandR)];
	w.footL = &w.fields[size_t(iFootL)];
	w.footR = &w.fields[size_t(iFootR)];
	FeaturePoints& fp = w.seg.features;
	fp.headTop = ends[size_t(iHead)];
	fp.handLeft = ends[size_t(iHandL)];
	fp.handRight = ends[size_t(iHandR)];
	fp.footLeft = ends[size_t(iFootL)];
	fp.footRight = ends[size_t(iFootR)];

	if (w.options.validate)
	{
		if (w.heightOf(fp.footLeft) > 0.12 || w.heightOf(fp.footRight) > 0.12)
			return "the two lowest extremities are not at the floor (not a standing figure)";
		if (w.heightOf(fp.headTop) < 0.88)
			return "no extremity at the top of the mesh (no head, or arms above the head)";
		if (w.heightOf(fp.handLeft) < 0.2 || w.heightOf(fp.handRight) < 0.2)
			return "two extremities besides the feet touch the ground (four legs?)";
	}
	return {};
}

/// Perineum: the paper takes the half-way point of the geodesic between the toe tips. We take the highest vertex
/// on the middle part of the shortest toe-to-toe paths (the crotch itself, also when the legs are not
/// symmetric). "On a shortest path" = d_left + d_right within 0.5% H of the toe-to-toe distance: a set, not one
/// traced path, so the choice does not depend on which foot the path is traced from (mirror symmetry).
/// Also the leg lengths (perineum -> toe tips).
std::string findPerineum(SegmentationWork& w)
{
	FeaturePoints& fp = w.seg.features;
	const Field& footL = *w.footL;
	const Field& footR = *w.footR;
	const double H = w.H;
	const double toeToToe = footL.d[size_t(fp.footRight)];
	if (!std::isfinite(toeToToe))
		return "the feet are not connected";
	{
		// Ties (a mirror pair at the same height) are broken by geometry, never by vertex index: nearer the middle
		// of the path, then larger x.
		std::array<double, 3> best = {-std::numeric_limits<double>::infinity(), 0.0, 0.0};
		for (int v = 0; v < w.n; ++v)
		{
			const double dl = footL.d[size_t(v)], dr = footR.d[size_t(v)];
			if (!(dl + dr <= toeToToe + 0.005 * H))
				continue;
			const double s = dl / (dl + dr);
			const std::array<double, 3> key = {w.y(v), -std::abs(dl - dr), w.mesh.V(v, 0)};
			if (s >= 0.3 && s <= 0.7 && key > best)
			{
				best = key;
				fp.perineum = v;
			}
		}
	}
	if (fp.perineum < 0)
		return "no path between the feet";
	SegmentationMeasures& m = w.seg.measures;
	m.legLengthLeft = footL.d[size_t(fp.perineum)];
	m.legLengthRight = footR.d[size_t(fp.perineum)];
	if (w.options.validate)
	{
		const double crotch = w.heightOf(fp.perineum);
		if (crotch < 0.3 || crotch > 0.65)
			return "the point between the legs is at " + std::to_string(int(std::lround(crotch * 100))) +
				   "% of the height (a standing human: 45-50%)";
	}
	return {};
}

/// Armpit: the geodesic from a fingertip to the toe tip on the same side runs along the arm, round the armpit
/// and down the flank. The armpit is the corner of that path: the vertex farthest from the chord between a point
/// near the elbow (hand + forearm = 0.254 H from the fingertip) and a point on the flank 0.1 H above the leg cut.
/// Returns the corner's depth (its distance from the chord); `*armpit` = -1 when there is none.
double findArmpit(const SegmentationWork& w, const Field& hand, int footPoint, const Field& foot, double legLength,
				  int* armpit)
{
	const double H = w.H;
	const std::vector<int> path = tracePath(hand.pred, footPoint);
	int a = -1, b = -1;
	for (int i = 0; i < int(path.size()); ++i)
	{
		const int v = path[size_t(i)];
		if (a < 0 && hand.d[size_t(v)] >= 0.254 * H)
			a = i;
		if (b < 0 && a >= 0 && foot.d[size_t(v)] <= legLength + 0.1 * H)
			b = i;
	}
	double depth = 0.0;
	const int i = deepestOnChord(w.mesh, path, a, b, &depth);
	*armpit = i >= 0 ? path[size_t(i)] : -1;
	return depth;
}

/// Both armpits and the arm lengths (armpit -> fingertip).
std::string findArmpits(SegmentationWork& w)
{
	FeaturePoints& fp = w.seg.features;
	SegmentationMeasures& m = w.seg.measures;
	const double depthL = findArmpit(w, *w.handL, fp.footLeft, *w.footL, m.legLengthLeft, &fp.armpitLeft);
	const double depthR = findArmpit(w, *w.handR, fp.footRight, *w.footR, m.legLengthRight, &fp.armpitRight);
	if (fp.armpitLeft < 0 || fp.armpitRight < 0)
		return "no armpit found between the arms and the flanks";
	if (w.options.validate && std::min(depthL, depthR) < 0.02 * w.H)
		return "the arms do not branch off the torso (no armpit corner)";
	m.armLengthLeft = w.handL->d[size_t(fp.armpitLeft)];
	m.armLengthRight = w.handR->d[size_t(fp.armpitRight)];
	return {};
}

/// Middle-layer cuts: elbows and knees at the narrowest cross-section in a band around the proportion-based
/// prediction.
void cutElbowsAndKnees(SegmentationWork& w)
{
	const SegmentationOptions& o = w.options;
	FeaturePoints& fp = w.seg.features;
	SegmentationMeasures& m = w.seg.measures;
	const Field& handL = *w.handL;
	const Field& handR = *w.handR;
	const Field& footL = *w.footL;
	const Field& footR = *w.footR;
	const double step = o.isolineStep * w.H;
	m.elbowDistanceLeft =
		narrowestLevel(w.mesh, handL.d, o.elbowFraction * m.armLengthLeft, o.elbowBand * m.armLengthLeft, step);
	m.elbowDistanceRight =
		narrowestLevel(w.mesh, handR.d, o.elbowFraction * m.armLengthRight, o.elbowBand * m.armLengthRight, step);
	m.kneeDistanceLeft =
		narrowestLevel(w.mesh, footL.d, o.kneeFraction * m.legLengthLeft, o.kneeBand * m.legLengthLeft, step);
	m.kneeDistanceRight =
		narrowestLevel(w.mesh, footR.d, o.kneeFraction * m.legLengthRight, o.kneeBand * m.legLengthRight, step);
	fp.elbowLeft = pathVertexAt(tracePath(handL.pred, fp.armpitLeft), handL.d, m.elbowDistanceLeft);
	fp.elbowRight = pathVertexAt(tracePath(handR.pred, fp.armpitRight), handR.d, m.elbowDistanceRight);
	fp.kneeLeft = pathVertexAt(tracePath(footL.pred, fp.perineum), footL.d, m.kneeDistanceLeft);
	fp.kneeRight = pathVertexAt(tracePath(footR.pred, fp.perineum), footR.d, m.kneeDistanceRight);
}

/// Neck: a planar cut perpendicular to the body axis (perineum -> head top). A geodesic isoline from the head top
/// would run through the mouth in front (the path over the face is longer than over the skull), so the head is
/// cut by the narrowest planar cross-section below the chin instead. Only the surface near the head
/// (geodesically within 0.35 H of the head top) is sliced, so raised hands never enter the profile.
/// Head = the piece above the cut that contains the head top.
void cutHead(SegmentationWork& w)
{
	const TriMesh& mesh = w.mesh;
	const SegmentationOptions& o = w.options;
	FeaturePoints& fp = w.seg.features;
	SegmentationMeasures& m = w.seg.measures;
	const double H = w.H;
	const Eigen::Vector3d top = vertex(mesh, fp.headTop);
	const Eigen::Vector3d bodyUp = (top - vertex(mesh, fp.perineum)).normalized();
	std::vector<double>& depth = w.neckDepth;
	depth.assign(static_cast<size_t>(w.n), std::numeric_limits<double>::infinity());
	for (int v = 0; v < w.n; ++v)
		if (w.head->d[size_t(v)] < 0.35 * H)
			depth[size_t(v)] = (top - vertex(mesh, v)).dot(bodyUp);
	m.neckDistance = narrowestLevel(mesh, depth, 0.5 * (o.neckBandMin + o.neckBandMax) * H,
		0.5 * (o.neckBandMax - o.neckBandMin) * H, o.isolineStep * H);
	fp.neck = pathVertexAt(tracePath(w.head->pred, fp.perineum), depth, m.neckDistance);
	std::vector<char>& inHead = w.inHead;
	inHead.assign(static_cast<size_t>(w.n), 0);
	std::vector<int> stack(1, fp.headTop);
	inHead[size_t(fp.headTop)] = 1;
	while (!stack.empty())
	{
		const int v = stack.back();
		stack.pop_back();
		const auto [begin, end] = w.solver->neighbors(v);
		for (const int* x = begin; x != end; ++x)
		{
			if (w.solver->isMeshEdge(x) && !inHead[size_t(*x)] && depth[size_t(*x)] < m.neckDistance)
			{
				inHead[size_t(*x)] = 1;
				stack.push_back(*x);
			}
		}
	}
}

/// Parts: the head as cut above; a vertex belongs to an arm / a leg when its geodesic distance to that end point
/// is below the limb's length; where two parts claim it, the one with the smaller relative distance wins. The rest
/// is torso. Then the checks that the parts have a human layout.
std::string assignParts(SegmentationWork& w)
{
	const SegmentationMeasures& m = w.seg.measures;
	const std::array<const Field*, 5> partField = {w.head, w.handL, w.handR, w.footL, w.footR};
	const std::array<double, 5> partLength = {
		m.neckDistance, m.armLengthLeft, m.armLengthRight, m.legLengthLeft, m.legLengthRight};
	w.part.assign(static_cast<size_t>(w.n), char(kTorso));
	for (int v = 0; v < w.n; ++v)
	{
		if (w.component[size_t(v)] != 0)
			continue;
		const bool inHead = w.inHead[size_t(v)] != 0;
		int best = inHead ? int(kHead) : int(kTorso), claims = inHead ? 1 : 0;
		double bestRatio = inHead ? 0.0 : 1.0;
		for (int p = kArmL; p <= kLegR; ++p)
		{
			const double ratio = partField[size_t(p)]->d[size_t(v)] / partLength[size_t(p)];
			if (ratio < 1.0)
			{
				++claims;
				if (ratio < bestRatio)
				{
					bestRatio = ratio;
					best = p;
				}
			}
		}
		w.contested += claims > 1 ? 1 : 0;
		w.contestedArea += claims > 1 ? w.area[size_t(v)] : 0.0;
		w.part[size_t(v)] = char(best);
		w.partArea[size_t(best)] += w.area[size_t(v)];
	}
	if (!w.options.validate)
		return {};
	// Thresholds are shares of the surface, not vertex counts: a finely tessellated part (a dense head) must not
	// change the verdict. 2% of the surface (it was 2% of the vertices; equal for an evenly tessellated body).
	if (w.contestedArea > 0.02 * w.totalArea)
		return "limb regions overlap on " + std::to_string(w.contested) + " vertices, " + percent(w.contestedArea / w.totalArea) +
			   " of the surface (not a human layout; at most 2%)";
	// A limb is a tube: its area is about 2 pi r L, far below the L^2-scale area of a blob's cap.
	const std::array<const char*, 4> limbName = {"left arm", "right arm", "left leg", "right leg"};
	for (int p = kArmL; p <= kLegR; ++p)
	{
		const double slender = w.partArea[size_t(p)] / (partLength[size_t(p)] * partLength[size_t(p)]);
		if (slender > 1.2)
			return std::string("the ") + limbName[size_t(p - kArmL)] + " is not a limb (area / length^2 = " +
				   std::to_string(slender).substr(0, 4) + ", a limb is below 1)";
	}
	const double torsoShare = w.partArea[kTorso] / w.totalArea;
	if (torsoShare < 0.15 || torsoShare > 0.7)
		return "the torso covers " + std::to_string(int(std::lround(torsoShare * 100))) +
			   "% of the surface (a human: 30-50%)";
	return {};
}

/// Torso frame: axis from the perineum to the centre of the neck cut; mid-sagittal plane = perpendicular bisector
/// of the armpits (its normal points to the subject's left).
struct TorsoFrame
{
	Eigen::Vector3d base = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::Zero();
	Eigen::Vector3d midpoint = Eigen::Vector3d::Zero(), sideNormal = Eigen::Vector3d::Zero();
	double axisLength2 = 0.0;
};

std::string torsoFrame(SegmentationWork& w, TorsoFrame* frame)
{
	const TriMesh& mesh = w.mesh;
	const FeaturePoints& fp = w.seg.features;
	Eigen::Vector3d neckCentre = Eigen::Vector3d::Zero();
	int neckRing = 0;
	for (int v = 0; v < w.n; ++v)
	{
		if (w.part[size_t(v)] != kHead || w.component[size_t(v)] != 0)
			continue;
		const auto [begin, end] = w.solver->neighbors(v);
		for (const int* x = begin; x != end; ++x)
		{
			if (w.solver->isMeshEdge(x) && w.part[size_t(*x)] != kHead)
			{
				neckCentre += vertex(mesh, v);
				++neckRing;
				break;
			}
		}
	}
	if (neckRing == 0)
		return "the head has no boundary";
	neckCentre /= neckRing;
	TorsoFrame& f = *frame;
	f.base = vertex(mesh, fp.perineum);
	f.axis = neckCentre - f.base;
	f.axisLength2 = f.axis.squaredNorm();
	const Eigen::Vector3d armpitL = vertex(mesh, fp.armpitLeft), armpitR = vertex(mesh, fp.armpitRight);
	f.midpoint = 0.5 * (armpitL + armpitR);
	f.sideNormal = armpitL - armpitR;
	if (w.options.validate && (!(f.axisLength2 > 0.0) || f.axis.y() < 0.3 * w.H || f.sideNormal.x() <= 0.0))
		return "the torso is not upright between the armpits";
	w.seg.measures.waistHeight = (f.base + w.options.waistFraction * f.axis).y();
	w.seg.measures.chestHeight = (f.base + w.options.chestFraction * f.axis).y();
	return {};
}

/// The region of a torso vertex: lower / middle / upper by the waist and chest cuts along the torso axis, left or
/// right of the mid-sagittal plane.
Region torsoRegion(const SegmentationWork& w, const TorsoFrame& f, int v)
{
	const Eigen::Vector3d p = vertex(w.mesh, v);
	const double s = (p - f.base).dot(f.axis) / f.axisLength2;
	// A vertex exactly on the mid-sagittal plane (the midline of a symmetric mesh) goes to the side of the
	// geodesically nearer hand; an exact tie there too (a mirror-symmetric edge graph) goes right.
	const double side = (p - f.midpoint).dot(f.sideNormal);
	const bool left = side != 0.0 ? side > 0.0 : w.handL->d[size_t(v)] < w.handR->d[size_t(v)];
	if (s < w.options.waistFraction)
		return left ? Region::TorsoLowerLeft : Region::TorsoLowerRight;
	if (s < w.options.chestFraction)
		return left ? Region::TorsoMiddleLeft : Region::TorsoMiddleRight;
	return left ? Region::TorsoUpperLeft : Region::TorsoUpperRight;
}

/// The 15 regions of the main component's vertices from their parts: limbs split at the elbow / knee, the torso
/// split in six (torsoRegion).
void labelRegions(SegmentationWork& w, const TorsoFrame& frame)
{
	const SegmentationMeasures& m = w.seg.measures;
	std::vector<Region>& labels = w.seg.labels;
	labels.assign(size_t(w.n), Region::Whole);
	for (int v = 0; v < w.n; ++v)
	{
		if (w.component[size_t(v)] != 0)
			continue;
		switch (w.part[size_t(v)])
		{
		case kHead: labels[size_t(v)] = Region::Head; break;
		case kArmL:
			labels[size_t(v)] = w.handL->d[size_t(v)] < m.elbowDistanceLeft ? Region::ArmLowerLeft : Region::ArmUpperLeft;
			break;
		case kArmR:
			labels[size_t(v)] =
				w.handR->d[size_t(v)] < m.elbowDistanceRight ? Region::ArmLowerRight : Region::ArmUpperRight;
			break;
		case kLegL:
			labels[size_t(v)] = w.footL->d[size_t(v)] < m.kneeDistanceLeft ? Region::LegLowerLeft : Region::LegUpperLeft;
			break;
		case kLegR:
			labels[size_t(v)] =
				w.footR->d[size_t(v)] < m.kneeDistanceRight ? Region::LegLowerRight : Region::LegUpperRight;
			break;
		default: labels[size_t(v)] = torsoRegion(w, frame, v);
		}
	}
}

/// Vertices off the body (enclosed or detached components): label of the nearest body vertex.
void labelOtherComponents(SegmentationWork& w)
{
	if (w.componentCount <= 1)
		return;
	const std::vector<int> nearest = nearestBodyVertex(w.mesh, w.layout);
	std::vector<Region>& labels = w.seg.labels;
	for (int v = 0; v < w.n; ++v)
		labels[size_t(v)] = labels[size_t(nearest[size_t(v)])];
}

/// Every region covers a minimum share of the surface (0.2%: it was 0.2% of the vertices, which a finely tessellated
/// head inflated until a coarse forearm failed) and has at least 5 vertices (one is not a region to fit).
std::string checkRegionSizes(const SegmentationWork& w)
{
	if (!w.options.validate)
		return {};
	const std::vector<int> counts = regionVertexCounts(w.seg.labels);
	std::vector<double> area(size_t(kBodyRegionCount) + 1, 0.0);
	for (int v = 0; v < w.n; ++v)
		if (w.component[size_t(v)] == 0)
			area[size_t(w.seg.labels[size_t(v)])] += w.area[size_t(v)];
	for (int r = 0; r < kBodyRegionCount; ++r)
	{
		if (counts[size_t(r)] < 5)
			return std::string("region ") + regionName(Region(r)) + " has " + std::to_string(counts[size_t(r)]) +
				   " vertices (need 5)";
		if (area[size_t(r)] < 0.002 * w.totalArea)
			return std::string("region ") + regionName(Region(r)) + " covers " + percent(area[size_t(r)] / w.totalArea) +
				   " of the surface (need 0.2%)";
	}
	return {};
}

/// The segmentation proper (the steps above, in order); returns a non-empty reason when the mesh does not look like
/// a standing human. Fills `seg` (labels, features, measures) as far as it got.
std::string segmentInto(const TriMesh& mesh, const SegmentationOptions& options, Segmentation& seg)
{
	SegmentationWork w(mesh, options, seg);
	std::string reason = measureMainComponent(w);
	if (!reason.empty())
		return reason;
	w.area = vertexAreas(mesh);
	w.solver.emplace(mesh, options.geodesics, w.layout.bridges);
	for (std::string (*step)(SegmentationWork&) :
		 {&findCentre, &findExtremities, &classifyExtremities, &findPerineum, &findArmpits})
	{
		reason = step(w);
		if (!reason.empty())
			return reason;
	}
	cutElbowsAndKnees(w);
	cutHead(w);
	reason = assignParts(w);
	if (!reason.empty())
		return reason;
	TorsoFrame frame;
	reason = torsoFrame(w, &frame);
	if (!reason.empty())
		return reason;
	labelRegions(w, frame);
	// Every region one connected piece: stray islands (tessellation noise at the cuts) join their neighbours.
	mergeStrayPieces(*w.solver, w.component, w.area, seg.labels, 8);
	labelOtherComponents(w);
	return checkRegionSizes(w);
}

} // namespace

Segmentation segmentBody(const TriMesh& mesh, const SegmentationOptions& options)
{
	const auto start = Clock::now();
	Segmentation seg;
	std::string reason;
	if (mesh.vertexCount() < 4 || mesh.faceCount() < 1)
		reason = "empty mesh";
	else
		reason = segmentInto(mesh, options, seg);
	if (!reason.empty())
	{
		Segmentation failed = wholeBodySegmentation(mesh, "not a standing human: " + reason);
		failed.features = seg.features;
		failed.measures = seg.measures;
		seg = std::move(failed);
	}
	else
		seg.ok = true;
	seg.milliseconds = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
	return seg;
}

Region mirrorRegion(Region region)
{
	switch (region)
	{
	case Region::TorsoLowerLeft: return Region::TorsoLowerRight;
	case Region::TorsoLowerRight: return Region::TorsoLowerLeft;
	case Region::TorsoMiddleLeft: return Region::TorsoMiddleRight;
	case Region::TorsoMiddleRight: return Region::TorsoMiddleLeft;
	case Region::TorsoUpperLeft: return Region::TorsoUpperRight;
	case Region::TorsoUpperRight: return Region::TorsoUpperLeft;
	case Region::ArmUpperLeft: return Region::ArmUpperRight;
	case Region::ArmUpperRight: return Region::ArmUpperLeft;
	case Region::ArmLowerLeft: return Region::ArmLowerRight;
	case Region::ArmLowerRight: return Region::ArmLowerLeft;
	case Region::LegUpperLeft: return Region::LegUpperRight;
	case Region::LegUpperRight: return Region::LegUpperLeft;
	case Region::LegLowerLeft: return Region::LegLowerRight;
	case Region::LegLowerRight: return Region::LegLowerLeft;
	default: return region;
	}
}

std::vector<int> regionVertexCounts(const std::vector<Region>& labels)
{
	std::vector<int> counts(size_t(kBodyRegionCount) + 1, 0);
	for (Region r : labels)
		if (int(r) >= 0 && int(r) <= kBodyRegionCount)
			++counts[size_t(r)];
	return counts;
}

std::vector<int> regionComponentCounts(const TriMesh& mesh, const std::vector<Region>& labels)
{
	std::vector<int> counts(size_t(kBodyRegionCount) + 1, 0);
	const int n = mesh.vertexCount();
	if (int(labels.size()) != n)
		return counts;
	// Union-find over mesh edges whose ends share a label.
	std::vector<int> parent(static_cast<size_t>(n));
	for (int v = 0; v < n; ++v)
		parent[size_t(v)] = v;
	auto root = [&](int v) {
		while (parent[size_t(v)] != v)
		{
			parent[size_t(v)] = parent[size_t(parent[size_t(v)])];
			v = parent[size_t(v)];
		}
		return v;
	};
	for (int f = 0; f < mesh.faceCount(); ++f)
	{
		for (int k = 0; k < 3; ++k)
		{
			const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
			if (labels[size_t(a)] == labels[size_t(b)])
				parent[size_t(root(a))] = root(b);
		}
	}
	for (int v = 0; v < n; ++v)
		if (root(v) == v && int(labels[size_t(v)]) >= 0 && int(labels[size_t(v)]) <= kBodyRegionCount)
			++counts[size_t(labels[size_t(v)])];
	return counts;
}

Eigen::Vector3d regionColor(Region region)
{
	switch (region)
	{
	case Region::Head: return {0.95, 0.85, 0.55};
	case Region::TorsoLowerLeft: return {0.85, 0.35, 0.30};
	case Region::TorsoLowerRight: return {0.45, 0.20, 0.60};
	case Region::TorsoMiddleLeft: return {0.95, 0.55, 0.35};
	case Region::TorsoMiddleRight: return {0.55, 0.40, 0.80};
	case Region::TorsoUpperLeft: return {0.98, 0.72, 0.50};
	case Region::TorsoUpperRight: return {0.70, 0.60, 0.92};
	case Region::ArmUpperLeft: return {0.90, 0.20, 0.20};
	case Region::ArmUpperRight: return {0.20, 0.35, 0.90};
	case Region::ArmLowerLeft: return {0.98, 0.50, 0.10};
	case Region::ArmLowerRight: return {0.15, 0.70, 0.95};
	case Region::LegUpperLeft: return {0.80, 0.75, 0.10};
	case Region::LegUpperRight: return {0.15, 0.65, 0.35};
	case Region::LegLowerLeft: return {0.95, 0.90, 0.30};
	case Region::LegLowerRight: return {0.40, 0.85, 0.50};
	default: return {0.65, 0.65, 0.65};
	}
}

TriMesh segmentationPreview(const TriMesh& mesh, const Segmentation& segmentation, Eigen::MatrixX3d* colors)
{
	const FeaturePoints& fp = segmentation.features;
	const std::array<int, 13> points = {fp.headTop, fp.handLeft, fp.handRight, fp.footLeft, fp.footRight, fp.neck,
		fp.elbowLeft, fp.elbowRight, fp.kneeLeft, fp.kneeRight, fp.perineum, fp.armpitLeft, fp.armpitRight};
	const int n = mesh.vertexCount();
	int markers = 0;
	for (int p : points)
		markers += p >= 0 && p < n ? 1 : 0;
	TriMesh out;
	out.V.resize(n + 6 * markers, 3);
	out.F.resize(mesh.faceCount() + 8 * markers, 3);
	out.V.topRows(n) = mesh.V;
	out.F.topRows(mesh.faceCount()) = mesh.F;
	Eigen::MatrixX3d c(out.V.rows(), 3);
	const bool labelled = int(segmentation.labels.size()) == n;
	for (int v = 0; v < n; ++v)
		c.row(v) = regionColor(labelled ? segmentation.labels[size_t(v)] : Region::Whole).transpose();
	// Octahedra of radius 1% of H: big enough to see, small enough not to hide the cut they mark.
	const double radius = 0.01 * (segmentation.height > 0.0 ? segmentation.height : 1.0);
	int vi = n, fi = mesh.faceCount();
	for (size_t k = 0; k < points.size(); ++k)
	{
		const int p = points[k];
		if (p < 0 || p >= n)
			continue;
		// End points black, middle-layer points white, inner points (perineum, armpits) magenta.
		const Eigen::Vector3d colour = k < 5 ? Eigen::Vector3d(0.0, 0.0, 0.0)
								: k < 10 ? Eigen::Vector3d(1.0, 1.0, 1.0) : Eigen::Vector3d(1.0, 0.0, 1.0);
		const Eigen::RowVector3d centre = mesh.V.row(p);
		for (int axis = 0; axis < 3; ++axis)
		{
			Eigen::RowVector3d offset = Eigen::RowVector3d::Zero();
			offset(axis) = radius;
			out.V.row(vi + 2 * axis) = centre + offset;
			out.V.row(vi + 2 * axis + 1) = centre - offset;
		}
		for (int j = 0; j < 6; ++j)
			c.row(vi + j) = colour.transpose();
		// Vertices: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z; eight outward-facing triangles.
		const int tri[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
		for (const auto& t : tri)
			out.F.row(fi++) << vi + t[0], vi + t[1], vi + t[2];
		vi += 6;
	}
	if (colors)
		*colors = c;
	return out;
}

} // namespace bodyfit
