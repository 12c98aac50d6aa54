#pragma once
/// \file segmentation.h
/// Semantic segmentation of a standing human body mesh into 16 regions (paper sec. 2; DESIGN.md sec. 2).
/// "left" and "right" are the subject's own: the bundled bodies face +z, so the subject's left is +x.

#include "bodyfit/types.h"

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

struct Segmentation
{
	bool ok = false;               ///< false: `failureReason` says why; labels are all Region::Whole
	std::string failureReason;
	std::vector<Region> labels;    ///< one per vertex of the input mesh
	FeaturePoints features;
	double height = 0.0;           ///< y extent of the mesh, metres
};

} // namespace bodyfit
