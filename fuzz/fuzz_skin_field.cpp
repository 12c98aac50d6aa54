// libFuzzer target: the skin field's side-file reader (bodyfit::parseSkinField, skin_field.h). Any input must either
// parse into a field whose layout is consistent (index entries in range, samples sized to the stored bricks) and that
// writes back to the same bytes, or raise bodyfit::FormatError; any other exception, crash, sanitizer report or huge
// allocation is a finding.
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/skin_field.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	const std::string bytes(reinterpret_cast<const char*>(data), size);
	try
	{
		const bodyfit::SkinField field = bodyfit::parseSkinField(bytes, "fuzz.skin");
		if (field.samples.size() != std::size_t(field.storedBricks()) * bodyfit::kSkinBrickSamples ||
			field.brickIndex.size() != std::size_t(field.brickCount()))
			std::abort();
		if (bodyfit::skinFieldBytes(field) != bytes) // the writer and the reader agree on every byte
			std::abort();
		// Sampling anywhere in (and around) the grid reads a finite value within the clamp.
		const Eigen::Vector3d size3 =
			field.voxel * bodyfit::kSkinBrickEdge * Eigen::Vector3d(field.nx, field.ny, field.nz);
		for (double t : {-0.1, 0.0, 0.37, 0.5, 0.99, 1.0, 1.1})
		{
			const double d = bodyfit::sample(field, field.origin + t * size3);
			if (!std::isfinite(d) || std::abs(d) > field.clamp)
				std::abort();
		}
	}
	catch (const bodyfit::FormatError&)
	{
	}
	return 0;
}
