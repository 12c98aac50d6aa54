// libFuzzer target: the drape scene reader (bodyfit::drape::parseSceneText: the nesting-depth check, nlohmann's
// parser, then parseScene) on any bytes. Every input must parse into a Scene or raise bodyfit::FormatError naming the
// key; nesting deeper than kMaxJsonDepth must be refused before a tree is built (seeds in tools/fuzz.sh reach it).
// The scene path is a fixed name in /tmp, so relative body and garment paths resolve to files that may or may not
// exist.
#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/errors.h"

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	const std::string text(reinterpret_cast<const char*>(data), size);
	try
	{
		const bodyfit::drape::Scene scene = bodyfit::drape::parseSceneText(text, "/tmp/bodyfit_fuzz/scene.json");
		(void)scene.effects.listed();
	}
	catch (const bodyfit::FormatError&)
	{
	}
	catch (const bodyfit::MeshLoadError&)
	{
	}
	catch (const bodyfit::InvalidInputError&)
	{
	}
	return 0;
}
