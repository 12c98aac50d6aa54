#pragma once
/// \file segmentation.h
/// Semantic segmentation of a standing human body mesh into 15 body regions (paper sec. 2; docs/DESIGN.md sec. 2).
/// "left" and "right" are the subject's own: the bundled bodies face +z, so the subject's left is +x.
///
/// Method (6 Dijkstra runs on the edge graph with face diagonals, see geodesics.h):
///  1. End points: farthest-point sampling in the geodesic metric from the vertex nearest the area centroid; the
///     first five picks are the extremities. Feet = the two lowest, head top = the highest other, hands = the rest.
///  2. Perineum: the highest vertex on the middle part of the shortest toe-to-toe paths. Leg length = geodesic
///     perineum -> toe tip. Armpit: the corner of the fingertip -> same-side toe geodesic (farthest from the chord
///     between a point near the elbow and a point on the flank). Arm length = geodesic armpit -> fingertip.
///  3. Cuts: elbow and knee at the narrowest isoline of the limb's geodesic field (interior local minimum of the
///     isoline length) in a band around a proportion of the limb length; the neck at the narrowest planar cross-
///     section perpendicular to the body axis below the head top (a geodesic isoline would cut through the mouth).
///  4. Regions: head = the piece above the neck plane; arm / leg = geodesic distance to its end point below the
///     limb length (hands and feet belong to the lower arm / lower leg); the rest is torso, split by the waist and
///     chest planes across the perineum -> neck axis and the perpendicular bisector plane of the armpits. Stray
///     islands of a region join the neighbouring region, so every region is one connected piece.
/// Ties in the decisions that shape the regions (end-point classification, perineum) are broken by coordinates,
/// not by vertex index; only exact ties in Dijkstra predecessors and in the farthest-point picks follow the vertex
/// order. Shuffling the vertex order of the bundled bodies changes no label (tests/fitting/test_segmentation.cpp).

#include "bodyfit/fitting/components.h"
#include "bodyfit/fitting/geodesics.h"
#include "bodyfit/fitting/types.h"

#include <array>
#include <string>
#include <vector>

namespace bodyfit
{

enum class Region : int
{
	Head = 0,
	TorsoLowerLeft,
	TorsoLowerRight,
	TorsoMiddleLeft,
	TorsoMiddleRight,
	TorsoUpperLeft,
	TorsoUpperRight,
	ArmUpperLeft,
	ArmUpperRight,
	ArmLowerLeft,
	ArmLowerRight,
	LegUpperLeft,
	LegUpperRight,
	LegLowerLeft,
	LegLowerRight,
	Whole, ///< the fallback when segmentation fails: the whole mesh is one region
};
constexpr int kBodyRegionCount = 15; ///< regions of a successful segmentation (Head .. LegLowerRight)

/// File-format name: "head", "torso.lower.left", "arm.upper.right", ..., "whole".
const char* regionName(Region region);
/// Inverse of regionName; returns false for an unknown name.
bool regionFromName(const std::string& name, Region* region);
bool isTorso(Region region);

/// Named feature points as vertex indices (-1 when not found).
struct FeaturePoints
{
	int headTop = -1, handLeft = -1, handRight = -1, footLeft = -1, footRight = -1;
	int neck = -1, elbowLeft = -1, elbowRight = -1, kneeLeft = -1, kneeRight = -1;
	int perineum = -1, armpitLeft = -1, armpitRight = -1;
};

/// Geodesic lengths and cut positions the segmentation used (metres; 0 when not reached).
struct SegmentationMeasures
{
	double armLengthLeft = 0.0, armLengthRight = 0.0;     ///< geodesic armpit -> hand point (fingertip)
	double legLengthLeft = 0.0, legLengthRight = 0.0;     ///< geodesic perineum -> foot point (toe tip)
	double elbowDistanceLeft = 0.0, elbowDistanceRight = 0.0; ///< geodesic hand point -> elbow cut
	double kneeDistanceLeft = 0.0, kneeDistanceRight = 0.0;   ///< geodesic foot point -> knee cut
	double neckDistance = 0.0;  ///< head top -> neck cut plane, along the body axis (perineum -> head top)
	double waistHeight = 0.0;   ///< y of the waist cut on the torso axis (perineum -> neck centre)
	double chestHeight = 0.0;   ///< y of the chest cut on the torso axis
};

struct Segmentation
{
	bool ok = false;               ///< false: `failureReason` says why; labels are all Region::Whole
	std::string failureReason;
	std::vector<Region> labels;    ///< one per vertex of the input mesh
	FeaturePoints features;
	double height = 0.0;           ///< y extent of the mesh, metres
	SegmentationMeasures measures;
	double milliseconds = 0.0;     ///< wall time of segmentBody
};

/// Tunables of segmentBody. Proportions are fractions of the stature H or of a limb's geodesic length; the
/// defaults come from Drillis & Contini via Winter (docs/DESIGN.md sec. 2) and are refined per body by
/// the narrowest cross-section in a band around each predicted cut.
struct SegmentationOptions
{
	GeodesicOptions geodesics;
	/// Which components form the body (components.h): separate parts closer than the gap are bridged for the
	/// geodesics, enclosed and detached ones take the label of the nearest body vertex.
	ComponentOptions components;
	/// Neck: the narrowest planar cross-section perpendicular to the body axis (interior local minimum), searched
	/// [min, max] x H below the head top.
	/// Head top -> chin is 0.13 H; the band reaches down to the base of the neck.
	double neckBandMin = 0.11;
	double neckBandMax = 0.22;
	/// Elbow: predicted at this fraction of the arm length (armpit -> fingertip) measured from the fingertip,
	/// searched within +- elbowBand (same unit). Hand + forearm = 0.254 H of an armpit -> fingertip length of
	/// about 0.39 H gives 0.65.
	double elbowFraction = 0.65;
	double elbowBand = 0.08;
	/// Knee: predicted at this fraction of the leg length (perineum -> toe tip) measured from the toe tip.
	/// Toe -> ankle along the foot (~0.15 H) + shank 0.246 H of a ~0.56 H geodesic leg gives 0.60 (the geodesic
	/// from the toe tip runs over the instep, so the leg is longer than the 0.485 H crotch height).
	double kneeFraction = 0.60;
	double kneeBand = 0.08;
	/// Torso cuts along the torso axis, as fractions of perineum -> neck centre:
	/// waist (navel 0.60 H) and chest (nipple line 0.72 H) with perineum 0.485 H and chin 0.87 H.
	double waistFraction = 0.30;
	double chestFraction = 0.61;
	/// Spacing of the isolines sampled for cross-section profiles, fraction of H.
	double isolineStep = 0.002;
	/// Plausibility checks that reject non-human meshes (see segmentBody). Disable only for experiments.
	bool validate = true;
};

/// Segments a standing human body (+y up, metres or any unit, facing +z so that the subject's left is +x).
/// Never throws for a mesh that passes requireUsable: when the mesh does not look like a standing human (sphere,
/// cube, torso only, animal, arms above the head, ...) it returns ok = false, a one-line failureReason and every
/// label Region::Whole. A body of several meshes is segmented as one (components.h: parts closer than the gap are
/// bridged); vertices of enclosed components (eyes, teeth) and detached ones take the label of the nearest body vertex.
/// Deterministic: same mesh -> same labels; re-indexing the vertices permutes the labels (see above).
Segmentation segmentBody(const TriMesh& mesh, const SegmentationOptions& options = {});

/// Region::Whole for every vertex (the generic path), ok = false with the given reason.
Segmentation wholeBodySegmentation(const TriMesh& mesh, const std::string& reason);

/// The same region on the other side of the body (head, whole: unchanged).
Region mirrorRegion(Region region);

/// Vertices per region, indexed by int(Region), size kBodyRegionCount + 1 (the last entry counts Region::Whole).
std::vector<int> regionVertexCounts(const std::vector<Region>& labels);

/// Connected pieces of each region (edge-connected vertices with the same label), indexed like regionVertexCounts;
/// 0 for an empty region.
std::vector<int> regionComponentCounts(const TriMesh& mesh, const std::vector<Region>& labels);

/// A distinct display colour per region (RGB in [0, 1]); left parts are warmer than the right ones.
Eigen::Vector3d regionColor(Region region);

/// The mesh coloured by region plus a small octahedron at every feature point (white, the hands and feet
/// black-tipped), ready for saveTriMesh(path, preview, &colors). `colors` gets one row per preview vertex.
TriMesh segmentationPreview(const TriMesh& mesh, const Segmentation& segmentation, Eigen::MatrixX3d* colors);

} // namespace bodyfit
