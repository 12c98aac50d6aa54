/// \file segmentation.cpp
/// Semantic segmentation of a standing human body (paper sec. 2; DESIGN.md sec. 2).

#include "bodyfit/segmentation.h"

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

} // namespace bodyfit
