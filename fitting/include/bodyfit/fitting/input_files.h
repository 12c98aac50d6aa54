#pragma once
/// \file input_files.h
/// The checks every reader of bodyfit runs on an input file before any parser sees it (docs/ROBUSTNESS.md,
/// section 7): only regular files are opened (a FIFO blocks `open` forever, a directory or a device fails inside a
/// third-party reader), JSON is bounded in size and nesting depth before a tree is built (deep nesting overflows
/// the stack of recursive code: nlohmann's copy, assimp's rapidjson), and mesh files get format checks before
/// assimp reads them (header counts against the file size, glTF node trees, files a mesh refers to).

#include <cstddef>
#include <string>
#include <string_view>

namespace bodyfit
{

/// Deepest nesting of JSON arrays/objects a bodyfit reader accepts. Fit files nest 3 levels, scenes 5, glTF 5-6;
/// the rest is room for members other tools add.
constexpr int kMaxJsonDepth = 64;

/// Largest fit or scene file read (bodyfit-fit writes about 600 bytes per ellipsoid: 100,000 ellipsoids fit).
constexpr std::size_t kMaxJsonFileBytes = std::size_t(64) << 20;

/// Why `path` cannot be read as an input file, or "" when it is a regular file that can be opened for reading.
/// The phrase completes "PATH: ...", e.g. "does not exist", "is a directory, not a file", "is a FIFO (named pipe),
/// not a regular file", "cannot be opened: Permission denied". Never blocks: the type is checked before opening
/// and the test open is non-blocking.
std::string inputFileProblem(const std::string& path);

/// "" when `text` nests arrays/objects at most `maxDepth` levels deep, otherwise a phrase naming the byte where the
/// limit is crossed. A byte scan (strings and comments skipped), so it runs before any parser builds a tree; it
/// counts exactly for valid JSON and may also refuse text that is invalid JSON anyway.
std::string jsonDepthProblem(std::string_view text, int maxDepth = kMaxJsonDepth);

/// Reads a JSON input file whole after inputFileProblem, the size cap kMaxJsonFileBytes and jsonDepthProblem.
/// `what` names the file in messages ("scene file", "fit file").
/// \throws FormatError "PATH: cannot open WHAT: <problem>" or "PATH: <problem>".
std::string readJsonInputFile(const std::string& path, const std::string& what);

/// The format checks loadTriMesh runs before assimp reads `path` (which must pass inputFileProblem):
/// PLY headers (well formed; declared element counts fit in the file), GLB headers (chunk lengths fit in the
/// file), glTF JSON (nesting depth, the node hierarchy is a tree of bounded depth, buffers fit in the files they
/// name, every file named by a buffer or image is a regular file), OBJ (every material library named is a regular
/// file; bounded numbers of objects, groups and materials). \throws MeshLoadError naming the file and the problem.
void requireSafeMeshFile(const std::string& path);

} // namespace bodyfit
