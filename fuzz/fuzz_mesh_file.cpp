// libFuzzer target: the mesh loader path (bodyfit::loadTriMesh: assimp import, validation, conversion, repair).
// The first byte picks the file extension (so assimp's format detection by name is exercised for every importer we
// care about), the rest is the file content, written to a per-process temporary file. Any input must load into a
// usable mesh or raise MeshLoadError / InvalidInputError, and the same for the rig loader (loadRig).
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/mesh_io.h"
#include "bodyfit/fitting/rig.h"

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace
{
const char* const kExtensions[] = {".obj", ".ply", ".stl", ".glb", ".gltf", ".off", ".fbx", ".dae", ".3ds", ".bin"};
constexpr int kExtensionCount = int(sizeof(kExtensions) / sizeof(kExtensions[0]));
} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
	if (size < 1)
		return 0;
	// /dev/shm (RAM) when present: the file round trip is most of the cost of one execution.
	static const std::string dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
	const std::string path =
		dir + "/bodyfit_fuzz_mesh_" + std::to_string(long(getpid())) + kExtensions[data[0] % kExtensionCount];
	FILE* f = std::fopen(path.c_str(), "wb");
	if (!f)
		return 0;
	if (size > 1)
		std::fwrite(data + 1, 1, size - 1, f);
	std::fclose(f);
	try
	{
		const bodyfit::LoadedMesh loaded = bodyfit::loadTriMesh(path);
		// What loading returns satisfies the fitter's preconditions.
		bodyfit::requireUsable(loaded.mesh, path);
		if (!loaded.mesh.V.allFinite())
			std::abort();
	}
	catch (const bodyfit::MeshLoadError&)
	{
	}
	catch (const bodyfit::InvalidInputError&)
	{
	}
	// The rig loader (rig.h) on the same bytes: a rig or one of the same two errors, with normalised weights.
	try
	{
		const bodyfit::Rig rig = bodyfit::loadRig(path, {{}, "", /*requireAnimation=*/false});
		for (int v = 0; v < rig.bindMesh.vertexCount(); ++v)
		{
			double sum = 0.0;
			for (int k = rig.weightStart[std::size_t(v)]; k < rig.weightStart[std::size_t(v) + 1]; ++k)
				sum += rig.weight[std::size_t(k)];
			if (!(std::abs(sum - 1.0) < 1e-9))
				std::abort();
		}
	}
	catch (const bodyfit::MeshLoadError&)
	{
	}
	catch (const bodyfit::InvalidInputError&)
	{
	}
	std::remove(path.c_str());
	return 0;
}
