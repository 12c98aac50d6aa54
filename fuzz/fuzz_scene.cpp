// libFuzzer target: the drape scene reader (bodyfit::drape::parseScene) on any JSON document. Bytes that are not
// JSON are dropped (nlohmann's parser is not ours); every document must parse into a Scene or raise
// bodyfit::FormatError naming the key. The scene path is a fixed name in the test data directory's parent, so
// relative body and garment paths resolve to files that may or may not exist.
#include "bodyfit/drape/scene.h"

#include "bodyfit/fitting/errors.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	const nlohmann::json document = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
	if (document.is_discarded())
		return 0;
	try
	{
		const bodyfit::drape::Scene scene = bodyfit::drape::parseScene(document, "/tmp/bodyfit_fuzz/scene.json");
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
