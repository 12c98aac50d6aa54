// libFuzzer target: the ellipsoid-set JSON reader (bodyfit::parseEllipsoidJson). Any input must either parse into
// a valid set (finite centres, proper rotations, positive axes) or raise bodyfit::FormatError; any other exception,
// crash or sanitizer report is a finding.
#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	const std::string text(reinterpret_cast<const char*>(data), size);
	try
	{
		const bodyfit::BodyFit fit = bodyfit::parseEllipsoidJson(text, "fuzz.json");
		for (const bodyfit::FittedEllipsoid& f : fit.ellipsoids)
			if (!f.ellipsoid.isValid())
				std::abort(); // the reader accepted an ellipsoid the library considers invalid
		// Written back, it must read again (the writer and the reader agree on the schema).
		const std::string written = bodyfit::toEllipsoidJson(fit);
		try
		{
			bodyfit::parseEllipsoidJson(written, "fuzz-roundtrip.json");
		}
		catch (const bodyfit::FormatError&)
		{
			std::abort();
		}
	}
	catch (const bodyfit::FormatError&)
	{
	}
	return 0;
}
