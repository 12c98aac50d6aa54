// Format checks loadTriMesh runs before assimp 5.2 reads a file (requireSafeMeshFile, input_files.h). Each check
// exists because assimp hangs, crashes, aborts or allocates without bound on the input it refuses; the inputs are
// catalogued in docs/ROBUSTNESS.md (sections 3 and 7) and kept in tests/data/robust_*.
#include "bodyfit/fitting/input_files.h"

#include "bodyfit/fitting/errors.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <set>
#include <vector>

namespace bodyfit
{

namespace
{

using Json = nlohmann::json;

/// Deepest glTF node hierarchy accepted: assimp's glTF readers and post-processing recurse once per level (a
/// 20,000-level chain overflowed the 8 MiB stack); skeletons of real bodies are 20-60 levels deep.
constexpr int kMaxGltfNodeDepth = 256;
/// Largest glTF JSON (a .gltf file, or a GLB JSON chunk) parsed by the check; embedded base64 buffers count.
constexpr std::uint64_t kMaxGltfJsonBytes = std::uint64_t(256) << 20;
/// assimp 5.2's OBJ reader makes one mesh per object, group or material statement, and its cost grows
/// quadratically in the number of objects (200,000 `o` lines: killed at 100 s) and of distinct materials (100,000
/// `usemtl` names: 3.5 GB); at the caps it takes under 0.5 s and 60 MB.
constexpr int kMaxObjMeshStatements = 10000;
constexpr int kMaxObjMaterials = 1000;

[[noreturn]] void refuse(const std::string& path, const std::string& why)
{
	throw MeshLoadError(path + ": " + why);
}

std::uint64_t fileSize(const std::string& path)
{
	std::ifstream in(path, std::ios::binary | std::ios::ate);
	const std::streamoff size = in.tellg();
	return size < 0 ? 0 : std::uint64_t(size);
}

std::string readBytes(const std::string& path, std::uint64_t offset, std::uint64_t count)
{
	std::ifstream in(path, std::ios::binary);
	in.seekg(std::streamoff(offset));
	std::string bytes(std::size_t(count), '\0');
	in.read(&bytes[0], std::streamsize(count));
	bytes.resize(std::size_t(std::max<std::streamsize>(in.gcount(), 0)));
	return bytes;
}

std::vector<std::string> tokens(const std::string& line)
{
	std::vector<std::string> tok;
	std::size_t i = 0;
	while (i < line.size())
	{
		while (i < line.size() && (line[i] == ' ' || line[i] == '\t'))
			++i;
		std::size_t j = i;
		while (j < line.size() && line[j] != ' ' && line[j] != '\t')
			++j;
		if (j > i)
			tok.push_back(line.substr(i, j - i));
		i = j;
	}
	return tok;
}

// --- files a mesh names (OBJ mtllib, glTF buffer/image uri) --------------------------------------------------

/// The paths a reader may open for a name inside `meshPath`: assimp joins the mesh's directory and the name
/// (even for an absolute name), so both that and an absolute name as written are checked.
std::vector<std::string> referencedCandidates(const std::string& meshPath, const std::string& name)
{
	const std::size_t slash = meshPath.find_last_of('/');
	const std::string dir = slash == std::string::npos ? "" : meshPath.substr(0, slash + 1);
	std::vector<std::string> out = {dir + name};
	if (!name.empty() && name[0] == '/' && !dir.empty())
		out.push_back(name);
	return out;
}

/// "" when every existing candidate is a regular file (and, when `mustExist`, one exists); the regular file found
/// is returned in `found`.
std::string referencedProblem(const std::string& meshPath, const std::string& name, bool mustExist,
							  std::string* found = nullptr)
{
	std::string missing;
	bool any = false;
	for (const std::string& candidate : referencedCandidates(meshPath, name))
	{
		const std::string problem = inputFileProblem(candidate);
		if (problem.empty())
		{
			any = true;
			if (found != nullptr)
				*found = candidate;
		}
		else if (problem.rfind("does not exist", 0) == 0)
			missing = "'" + candidate + "' " + problem;
		else
			return "'" + candidate + "' " + problem;
	}
	return mustExist && !any ? missing : "";
}

/// glTF URIs may be percent-encoded ("my%20buffer.bin").
std::string percentDecoded(const std::string& uri)
{
	std::string out;
	for (std::size_t i = 0; i < uri.size(); ++i)
	{
		if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit((unsigned char)uri[i + 1]) &&
			std::isxdigit((unsigned char)uri[i + 2]))
		{
			out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
			i += 2;
		}
		else
			out += uri[i];
	}
	return out;
}

// --- PLY -----------------------------------------------------------------------------------------------------

struct PlyProperty
{
	int size = 0;          ///< bytes of a scalar, or of a list's count
	int itemSize = 0;      ///< bytes of each list entry; 0 for a scalar
	bool signedCount = false; ///< a list count of a signed type (assimp turns -1 into 4294967295)
};

struct PlyElement
{
	std::string name;
	std::uint64_t count = 0;
	int properties = 0;
	std::uint64_t minBinaryBytes = 0; ///< scalar sizes + list count sizes (a list with no entries)
	std::vector<PlyProperty> layout;
	bool hasList = false;
};

struct PlyHeader
{
	bool ascii = true;
	bool bigEndian = false;
	std::uint64_t headerBytes = 0;
	std::vector<PlyElement> elements;
};

int plyTypeSize(const std::string& t)
{
	static const std::pair<const char*, int> kTypes[] = {
		{"char", 1},  {"uchar", 1},  {"short", 2},  {"ushort", 2},	{"int", 4},		{"uint", 4},
		{"float", 4}, {"double", 8}, {"int8", 1},	{"uint8", 1},	{"int16", 2},	{"uint16", 2},
		{"int32", 4}, {"uint32", 4}, {"float32", 4}, {"float64", 8}};
	for (const auto& k : kTypes)
		if (t == k.first)
			return k.second;
	return 0;
}

/// One header line after the magic; returns false at end_header. \throws MeshLoadError naming the line.
bool readPlyHeaderLine(const std::string& path, int lineNo, const std::vector<std::string>& tok, PlyHeader& h,
					   bool& haveFormat)
{
	auto fail = [&](const std::string& why) {
		refuse(path, "malformed PLY header, line " + std::to_string(lineNo) + ": " + why);
	};
	if (tok.empty())
		fail("empty line");
	const std::string& key = tok[0];
	if (key == "comment" || key == "obj_info")
		return true;
	if (key == "end_header")
	{
		if (!haveFormat)
			fail("no format line");
		return false;
	}
	if (key == "format")
	{
		if (tok.size() != 3 || (tok[1] != "ascii" && tok[1] != "binary_little_endian" && tok[1] != "binary_big_endian"))
			fail("expected 'format ascii|binary_little_endian|binary_big_endian VERSION'");
		haveFormat = true;
		h.ascii = tok[1] == "ascii";
		h.bigEndian = tok[1] == "binary_big_endian";
	}
	else if (key == "element")
	{
		if (tok.size() != 3 || tok[2].find_first_not_of("0123456789") != std::string::npos || tok[2].size() > 10)
			fail("expected 'element NAME COUNT'");
		h.elements.push_back({tok[1], std::stoull(tok[2]), 0, 0, {}, false});
	}
	else if (key == "property")
	{
		const bool list = tok.size() == 5 && tok[1] == "list" && plyTypeSize(tok[2]) > 0 && plyTypeSize(tok[3]) > 0;
		const bool scalar = tok.size() == 3 && plyTypeSize(tok[1]) > 0;
		if (!list && !scalar)
			fail("expected 'property TYPE NAME' or 'property list TYPE TYPE NAME'");
		if (h.elements.empty())
			fail("property before any element");
		PlyElement& e = h.elements.back();
		e.properties += 1;
		e.minBinaryBytes += std::uint64_t(plyTypeSize(list ? tok[2] : tok[1]));
		const std::string countType = list ? tok[2] : "";
		const bool signedCount = countType == "char" || countType == "short" || countType == "int" ||
								 countType == "int8" || countType == "int16" || countType == "int32";
		e.layout.push_back({plyTypeSize(list ? tok[2] : tok[1]), list ? plyTypeSize(tok[3]) : 0, signedCount});
		e.hasList = e.hasList || list;
	}
	else
		fail("unknown keyword");
	return true;
}

/// assimp 5.2's PLY reader loops forever on some malformed headers (found by fuzz_mesh_file: tests/data/
/// robust_fuzz_ply_hang.ply), so a file that starts with the PLY magic must have a well-formed header:
/// format, element NAME COUNT, property TYPE NAME, property list TYPE TYPE NAME, comment, obj_info, end_header
/// (within the first 64 KiB).
PlyHeader readPlyHeader(const std::string& path, const std::string& head)
{
	PlyHeader h;
	std::size_t pos = head.find('\n');
	std::string line = head.substr(0, pos);
	if (!line.empty() && line.back() == '\r')
		line.pop_back();
	// assimp also takes "ply" followed by other bytes for PLY magic and can hang on the rest (fuzz_mesh_file:
	// tests/data/robust_fuzz_ply_magic_hang.ply starts with "ply/"): the magic line must be exactly "ply".
	if (line != "ply")
		refuse(path, "malformed PLY header, line 1: expected 'ply'");
	bool haveFormat = false;
	for (int lineNo = 2; pos != std::string::npos; ++lineNo)
	{
		const std::size_t start = pos + 1;
		pos = head.find('\n', start);
		if (pos == std::string::npos)
			refuse(path, "malformed PLY header, line " + std::to_string(lineNo) +
							 (head.size() >= 65536 ? ": no end_header in the first 64 KiB" : ": no end_header"));
		line = head.substr(start, pos - start);
		if (!line.empty() && line.back() == '\r')
			line.pop_back();
		if (!readPlyHeaderLine(path, lineNo, tokens(line), h, haveFormat))
		{
			h.headerBytes = pos + 1;
			return h;
		}
	}
	refuse(path, "malformed PLY header, line 0: no end_header");
}

/// Declared element counts must fit in the bytes after the header: a binary element takes at least its scalar
/// sizes plus its list counts, an ASCII element at least 2 bytes per property (a digit and a separator). A PLY
/// claiming 4 billion vertices in a few bytes otherwise makes assimp allocate for all of them (std::bad_alloc).
void requirePlyCountsFit(const std::string& path, const PlyHeader& h)
{
	const std::uint64_t body = fileSize(path) - std::min(fileSize(path), h.headerBytes);
	std::uint64_t needed = 0;
	for (const PlyElement& e : h.elements)
	{
		const std::uint64_t each = h.ascii ? 2 * std::uint64_t(e.properties) : e.minBinaryBytes;
		needed += e.count * each; // count < 1e10 and each < 1e5: no overflow
		if (needed > body + 1) // + 1: the last ASCII line may lack its newline
			refuse(path, "PLY header declares " + std::to_string(e.count) + " '" + e.name + "' elements (" +
							 (h.ascii ? "ASCII" : "binary") + ", at least " + std::to_string(each) +
							 " bytes each) but the file has only " + std::to_string(body) + " bytes of data");
	}
}

/// Sequential reads of a PLY body through a 1 MiB buffer (the list scan touches every byte once).
class PlyBodyReader
{
public:
	PlyBodyReader(const std::string& path, std::uint64_t offset) : in_(path, std::ios::binary)
	{
		in_.seekg(std::streamoff(offset));
	}
	/// Next byte, or -1 at the end.
	int get()
	{
		if (pos_ == buf_.size())
		{
			buf_.resize(1 << 20);
			in_.read(&buf_[0], std::streamsize(buf_.size()));
			buf_.resize(std::size_t(std::max<std::streamsize>(in_.gcount(), 0)));
			pos_ = 0;
			if (buf_.empty())
				return -1;
		}
		++consumed_;
		return (unsigned char)buf_[pos_++];
	}
	/// A little- or big-endian unsigned of `size` bytes; false at the end.
	bool unsignedValue(int size, bool bigEndian, std::uint64_t& v)
	{
		v = 0;
		for (int i = 0; i < size; ++i)
		{
			const int c = get();
			if (c < 0)
				return false;
			v = bigEndian ? (v << 8) | std::uint64_t(c) : v | (std::uint64_t(c) << (8 * i));
		}
		return true;
	}
	/// The next whitespace-separated ASCII token; empty at the end.
	std::string token()
	{
		std::string t;
		for (int c = get(); c >= 0; c = get())
		{
			if (c == ' ' || c == '\t' || c == '\n' || c == '\r')
			{
				if (!t.empty())
					return t;
				continue;
			}
			t += char(c);
		}
		return t;
	}
	std::uint64_t consumed() const { return consumed_; }

private:
	std::ifstream in_;
	std::string buf_;
	std::size_t pos_ = 0;
	std::uint64_t consumed_ = 0;
};

/// ASCII bodies, whatever the alignment: assimp 5.2 reads one element per line, where a NUL, CR or form feed also ends
/// a line, so a count can sit where a token scan does not expect it (fuzz_mesh_file:
/// tests/data/robust_fuzz_ply_list_nul2.ply). No unsigned number in a body with lists may exceed what a list in
/// the file could hold (2 bytes an entry) or 2^24 (assimp's reservation of 8 bytes an entry then stays <= 128 MiB).
void requirePlyAsciiNumbersBounded(const std::string& path, const PlyHeader& h)
{
	if (!std::any_of(h.elements.begin(), h.elements.end(), [](const PlyElement& e) { return e.hasList; }))
		return;
	const std::uint64_t body = fileSize(path) - std::min(fileSize(path), h.headerBytes);
	const std::uint64_t bound = std::max<std::uint64_t>(body / 2 + 1, std::uint64_t(1) << 24);
	PlyBodyReader r(path, h.headerBytes);
	std::uint64_t value = 0;
	int digits = 0;
	bool tokenStart = true, counting = false; // a number counts from a token's start, as assimp reads a count
	for (;;)
	{
		const int c = r.get();
		if (c >= '0' && c <= '9' && (tokenStart || counting))
		{
			value = counting ? value * 10 + std::uint64_t(c - '0') : std::uint64_t(c - '0');
			digits = counting ? digits + 1 : 1;
			counting = digits < 20;
			tokenStart = false;
			if (counting)
				continue;
		}
		if ((counting || digits >= 20) && (digits >= 20 || value > bound))
			refuse(path, "PLY body holds the count-like number " +
							 (digits >= 20 ? std::string("of 20 or more digits") : std::to_string(value)) + " at byte " +
							 std::to_string(h.headerBytes + r.consumed()) + ", more entries than a list in this file can hold");
		counting = false;
		digits = 0;
		if (c < 0)
			return;
		tokenStart = c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\0' || c == '\f';
	}
}

/// Every list count in the body fits in what is left of the file (assimp reserves the declared number of entries:
/// a face claiming 4e9 indices was std::bad_alloc). Stops at the first short read: assimp reports truncation.
void requirePlyListsFit(const std::string& path, const PlyHeader& h)
{
	const std::uint64_t body = fileSize(path) - std::min(fileSize(path), h.headerBytes);
	PlyBodyReader r(path, h.headerBytes);
	for (const PlyElement& e : h.elements)
		for (std::uint64_t i = 0; i < e.count; ++i)
			for (const PlyProperty& p : e.layout)
			{
				std::uint64_t n = 1;
				if (h.ascii)
				{
					const std::string t = r.token();
					if (t.empty())
						return;
					if (p.itemSize == 0)
						continue;
					// assimp reads a count's leading digits and ignores what follows ("4000000000\0\0", found by
					// fuzz_mesh_file: tests/data/robust_fuzz_ply_list_nul.ply)
					if (p.signedCount && t.size() > 1 && t[0] == '-' && std::isdigit((unsigned char)t[1]))
						refuse(path, "PLY '" + e.name + "' " + std::to_string(i) + " declares a list of " + t + " entries");
					const std::size_t digits = std::min(t.find_first_not_of("0123456789"), t.size());
					if (digits == 0)
						return; // no count at all: assimp reports it
					n = digits > 19 ? ~std::uint64_t(0) : std::stoull(t.substr(0, digits));
				}
				else if (p.itemSize == 0)
				{
					for (int b = 0; b < p.size; ++b)
						if (r.get() < 0)
							return;
					continue;
				}
				else if (!r.unsignedValue(p.size, h.bigEndian, n))
					return;
				if (p.itemSize == 0)
					continue;
				const std::uint64_t left = body - std::min(body, r.consumed());
				if (n > left / (h.ascii ? 2 : std::uint64_t(p.itemSize)) + 1)
					refuse(path, "PLY '" + e.name + "' " + std::to_string(i) + " declares a list of " +
									 std::to_string(n) + " entries but only " + std::to_string(left) + " bytes follow");
				for (std::uint64_t k = 0; k < n; ++k)
				{
					if (h.ascii && r.token().empty())
						return;
					for (int b = 0; !h.ascii && b < p.itemSize; ++b)
						if (r.get() < 0)
							return;
				}
			}
}

// --- glTF / GLB ----------------------------------------------------------------------------------------------

/// What the glTF checks need to know about the file the JSON came from.
struct GltfContext
{
	std::string path;
	bool glb = false;
	std::uint64_t binChunkBytes = 0; ///< GLB: bytes of the binary chunk (v2) or body (v1); 0 when none
};

/// Node index (v2: array position; v1: object key) -> children, as indices.
std::vector<std::vector<std::size_t>> gltfChildren(const GltfContext& g, const Json& nodes)
{
	std::vector<std::string> keys;
	if (nodes.is_object())
		for (auto it = nodes.begin(); it != nodes.end(); ++it)
			keys.push_back(it.key());
	const std::size_t n = nodes.size();
	std::vector<std::vector<std::size_t>> children(n);
	std::size_t i = 0;
	for (auto it = nodes.begin(); it != nodes.end(); ++it, ++i)
	{
		if (!it->is_object() || !it->contains("children"))
			continue;
		const Json& list = (*it)["children"];
		if (!list.is_array())
			refuse(g.path, "glTF node " + std::to_string(i) + ": children is not an array");
		for (const Json& c : list)
		{
			std::size_t index = n;
			if (c.is_number_unsigned() && c.get<std::uint64_t>() < n)
				index = std::size_t(c.get<std::uint64_t>());
			else if (c.is_string())
				index = std::size_t(std::find(keys.begin(), keys.end(), c.get<std::string>()) - keys.begin());
			if (index >= n)
				refuse(g.path, "glTF node " + std::to_string(i) + ": child " + c.dump() + " is not a node");
			children[i].push_back(index);
		}
	}
	return children;
}

/// glTF nodes form a forest (each node has at most one parent, no cycles) of bounded depth.
void requireGltfNodeTree(const GltfContext& g, const Json& doc)
{
	if (!doc.contains("nodes") || !(doc["nodes"].is_array() || doc["nodes"].is_object()))
		return;
	const std::vector<std::vector<std::size_t>> children = gltfChildren(g, doc["nodes"]);
	const std::size_t n = children.size();
	std::vector<int> parents(n, 0);
	for (std::size_t i = 0; i < n; ++i)
		for (std::size_t c : children[i])
			if (++parents[c] > 1)
				refuse(g.path, "glTF node " + std::to_string(c) + " has more than one parent (nodes must form a tree)");
	std::vector<std::pair<std::size_t, int>> stack; // (node, depth), iterative: the depth is what is being bounded
	for (std::size_t i = 0; i < n; ++i)
		if (parents[i] == 0)
			stack.push_back({i, 1});
	std::size_t reached = 0;
	while (!stack.empty())
	{
		const auto [node, depth] = stack.back();
		stack.pop_back();
		++reached;
		if (depth > kMaxGltfNodeDepth)
			refuse(g.path, "glTF node hierarchy is deeper than " + std::to_string(kMaxGltfNodeDepth) + " levels");
		for (std::size_t c : children[node])
			stack.push_back({c, depth + 1});
	}
	if (reached < n)
		refuse(g.path, "glTF nodes form a cycle (" + std::to_string(n - reached) + " nodes are their own ancestors)");
}

/// Bytes a "data:...;base64,..." URI decodes to (an upper bound for other encodings: the payload length).
std::uint64_t dataUriBytes(const std::string& uri)
{
	const std::size_t comma = uri.find(',');
	const std::uint64_t payload = comma == std::string::npos ? 0 : uri.size() - comma - 1;
	const bool base64 = comma != std::string::npos && uri.rfind(";base64", comma) != std::string::npos;
	if (!base64)
		return payload;
	const std::uint64_t padding = uri.size() - 1 - std::min(uri.find_last_not_of('='), uri.size() - 1);
	return payload / 4 * 3 - std::min<std::uint64_t>(padding, 2);
}

/// Every buffer fits in what it names (a data URI, an external file, the GLB binary chunk), and every external
/// buffer or image is a regular file: assimp allocates byteLength bytes before reading, and opens what a uri
/// names (a FIFO blocks).
void requireGltfBuffers(const GltfContext& g, const Json& doc, const char* key, bool isBuffer)
{
	if (!doc.contains(key) || !(doc[key].is_array() || doc[key].is_object()))
		return;
	std::size_t i = 0;
	for (auto it = doc[key].begin(); it != doc[key].end(); ++it, ++i)
	{
		if (!it->is_object())
			continue;
		const std::string where = std::string("glTF ") + key + "[" + std::to_string(i) + "]";
		const std::uint64_t declared = it->contains("byteLength") && (*it)["byteLength"].is_number_unsigned()
										   ? (*it)["byteLength"].get<std::uint64_t>()
										   : 0;
		std::uint64_t available = g.binChunkBytes;
		const bool hasUri = it->contains("uri") && (*it)["uri"].is_string();
		const std::string uri = hasUri ? (*it)["uri"].get<std::string>() : "";
		if (hasUri && uri.rfind("data:", 0) == 0)
			available = dataUriBytes(uri);
		else if (hasUri)
		{
			std::string found, missing;
			for (const std::string& name : {uri, percentDecoded(uri)})
			{
				const std::string problem = referencedProblem(g.path, name, true, &found);
				if (!problem.empty() && problem.find("' does not exist") == std::string::npos)
					refuse(g.path, where + ".uri names " + problem);
				missing = missing.empty() ? problem : missing;
			}
			if (found.empty() && isBuffer)
				refuse(g.path, where + ".uri names " + missing);
			available = found.empty() ? 0 : fileSize(found);
		}
		else if (!g.glb)
			continue; // no data at all: assimp reports it
		if (isBuffer && declared > available)
			refuse(g.path, where + ".byteLength is " + std::to_string(declared) + " but its data has only " +
							   std::to_string(available) + " bytes");
	}
}

// glTF 2.0 references: every index names an existing object and every accessor reads inside its buffer view,
// every view inside its buffer. assimp 5.2's glTF2 reader trusts them (a skin without inverseBindMatrices, from a
// fuzzed GLB now in tests/data/robust_fuzz_glb_skin_no_ibm.glb, was a null-pointer crash inside Importer::ReadFile).

/// Largest accessor count accepted without a buffer view (assimp allocates count elements of zeros): 2^26.
constexpr std::uint64_t kMaxGltfUnbackedCount = std::uint64_t(1) << 26;

/// The array `key` of the document (empty when absent). \throws MeshLoadError when it is there but not an array.
const Json& gltfArray(const GltfContext& g, const Json& doc, const char* key)
{
	static const Json empty = Json::array();
	if (!doc.contains(key))
		return empty;
	if (!doc[key].is_array())
		refuse(g.path, std::string("glTF ") + key + " is not an array");
	return doc[key];
}

/// `v` as an index into an array of `count` objects named `what`. \throws MeshLoadError naming `where` when it is
/// not an unsigned integer below `count`.
long long gltfIndexValue(const GltfContext& g, const Json& v, std::size_t count, const char* what,
						 const std::string& where)
{
	if (!v.is_number_unsigned() || v.get<std::uint64_t>() >= count)
		refuse(g.path, where + " is " + v.dump() + ", not one of the " + std::to_string(count) + " " + what);
	return (long long)v.get<std::uint64_t>();
}

/// obj[key] as an index into an array of `count` objects named `what`; -1 when absent and not `required`.
/// \throws MeshLoadError naming `where` when it is not an unsigned integer below `count`.
long long gltfIndex(const GltfContext& g, const Json& obj, const char* key, std::size_t count, const char* what,
					const std::string& where, bool required)
{
	if (!obj.is_object() || !obj.contains(key))
	{
		if (required)
			refuse(g.path, where + " has no " + key);
		return -1;
	}
	return gltfIndexValue(g, obj[key], count, what, where + "." + key);
}

/// obj[key] as an unsigned number (`fallback` when absent). \throws MeshLoadError when it is not one.
std::uint64_t gltfUnsigned(const GltfContext& g, const Json& obj, const char* key, std::uint64_t fallback,
						   const std::string& where)
{
	if (!obj.is_object() || !obj.contains(key))
		return fallback;
	if (!obj[key].is_number_unsigned())
		refuse(g.path, where + "." + key + " is " + obj[key].dump() + ", not an unsigned integer");
	return obj[key].get<std::uint64_t>();
}

std::string gltfWhere(const char* key, std::size_t i)
{
	return std::string("glTF ") + key + "[" + std::to_string(i) + "]";
}

/// Every buffer view lies inside its buffer (byteOffset + byteLength <= the buffer's byteLength) with a stride in
/// [4, 252] when it has one (the glTF 2.0 limits).
void requireGltfBufferViews(const GltfContext& g, const Json& doc)
{
	const Json& buffers = gltfArray(g, doc, "buffers");
	const Json& views = gltfArray(g, doc, "bufferViews");
	for (std::size_t i = 0; i < views.size(); ++i)
	{
		const std::string where = gltfWhere("bufferViews", i);
		const long long b = gltfIndex(g, views[i], "buffer", buffers.size(), "buffers", where, true);
		const std::uint64_t offset = gltfUnsigned(g, views[i], "byteOffset", 0, where);
		const std::uint64_t length = gltfUnsigned(g, views[i], "byteLength", 0, where);
		const std::uint64_t bufferLength = gltfUnsigned(g, buffers[std::size_t(b)], "byteLength", 0, gltfWhere("buffers", std::size_t(b)));
		if (offset > bufferLength || length > bufferLength - offset)
			refuse(g.path, where + " (bytes " + std::to_string(offset) + " + " + std::to_string(length) +
							   ") runs past the end of buffer " + std::to_string(b) + " (" +
							   std::to_string(bufferLength) + " bytes)");
		const std::uint64_t stride = gltfUnsigned(g, views[i], "byteStride", 0, where);
		if (views[i].contains("byteStride") && (stride < 4 || stride > 252))
			refuse(g.path, where + ".byteStride is " + std::to_string(stride) + " (glTF allows 4-252)");
	}
}

/// Bytes of one element of an accessor (matrix columns padded to 4 bytes, as glTF lays them out); 0 when the
/// component type or the type is not a glTF 2.0 one.
std::uint64_t gltfElementBytes(std::uint64_t componentType, const std::string& type)
{
	std::uint64_t component = 0;
	switch (componentType)
	{
	case 5120: case 5121: component = 1; break;
	case 5122: case 5123: component = 2; break;
	case 5125: case 5126: component = 4; break;
	default: return 0;
	}
	const std::vector<std::pair<std::string, int>> vectors = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}};
	for (const auto& [name, n] : vectors)
		if (type == name)
			return component * std::uint64_t(n);
	for (int n = 2; n <= 4; ++n)
		if (type == "MAT" + std::to_string(n))
			return std::uint64_t(n) * ((component * std::uint64_t(n) + 3) / 4 * 4);
	return 0;
}

/// `count` elements of `elementBytes`, `stride` apart (0: tightly packed), from `offset` fit in buffer view `view`.
void requireGltfReadInView(const GltfContext& g, const Json& doc, long long view, std::uint64_t offset,
						   std::uint64_t count, std::uint64_t elementBytes, std::uint64_t stride, const std::string& where)
{
	const Json& v = doc["bufferViews"][std::size_t(view)];
	const std::uint64_t length = gltfUnsigned(g, v, "byteLength", 0, gltfWhere("bufferViews", std::size_t(view)));
	if (stride == 0)
		stride = elementBytes;
	// offset + (count - 1) * stride + elementBytes <= length, without overflow (count >= 1, stride <= 252).
	const bool fits = offset <= length && elementBytes <= length - offset &&
					  (count - 1) <= (length - offset - elementBytes) / std::max<std::uint64_t>(stride, 1);
	if (!fits)
		refuse(g.path, where + ": " + std::to_string(count) + " elements of " + std::to_string(elementBytes) +
						   " bytes from byte " + std::to_string(offset) + " run past the end of buffer view " +
						   std::to_string(view) + " (" + std::to_string(length) + " bytes)");
}

/// A sparse accessor's indices and values lie inside their views and number at most the accessor's count.
void requireGltfSparse(const GltfContext& g, const Json& doc, const Json& sparse, std::uint64_t count,
					   std::uint64_t elementBytes, const std::string& where)
{
	const std::size_t views = gltfArray(g, doc, "bufferViews").size();
	const std::uint64_t n = gltfUnsigned(g, sparse, "count", 0, where + ".sparse");
	if (n < 1 || n > count)
		refuse(g.path, where + ".sparse.count is " + std::to_string(n) + " (1 to the accessor's " +
						   std::to_string(count) + ")");
	for (const char* part : {"indices", "values"})
	{
		const std::string at = where + ".sparse." + part;
		if (!sparse.contains(part) || !sparse[part].is_object())
			refuse(g.path, at + " is missing");
		const Json& p = sparse[part];
		const long long view = gltfIndex(g, p, "bufferView", views, "bufferViews", at, true);
		std::uint64_t bytes = elementBytes;
		if (std::string(part) == "indices")
		{
			const std::uint64_t type = gltfUnsigned(g, p, "componentType", 0, at);
			bytes = type == 5121 ? 1 : type == 5123 ? 2 : type == 5125 ? 4 : 0;
			if (bytes == 0)
				refuse(g.path, at + ".componentType is " + std::to_string(type) + " (5121, 5123 or 5125)");
		}
		requireGltfReadInView(g, doc, view, gltfUnsigned(g, p, "byteOffset", 0, at), n, bytes, 0, at);
	}
}

/// Every accessor has a glTF 2.0 component type and type, count >= 1, and reads inside its buffer view (or, with
/// no view, is small enough for assimp to allocate); its sparse part likewise.
void requireGltfAccessors(const GltfContext& g, const Json& doc)
{
	const Json& accessors = gltfArray(g, doc, "accessors");
	const Json& views = gltfArray(g, doc, "bufferViews");
	for (std::size_t i = 0; i < accessors.size(); ++i)
	{
		const Json& a = accessors[i];
		const std::string where = gltfWhere("accessors", i);
		const std::uint64_t componentType = gltfUnsigned(g, a, "componentType", 0, where);
		const std::string type = a.is_object() && a.contains("type") && a["type"].is_string() ? a["type"].get<std::string>() : "";
		const std::uint64_t element = gltfElementBytes(componentType, type);
		if (element == 0)
			refuse(g.path, where + " has component type " + std::to_string(componentType) + " and type '" + type +
							   "' (not a glTF 2.0 accessor)");
		const std::uint64_t count = gltfUnsigned(g, a, "count", 0, where);
		if (count < 1)
			refuse(g.path, where + ".count is 0 (at least 1)");
		const long long view = gltfIndex(g, a, "bufferView", views.size(), "bufferViews", where, false);
		if (view >= 0)
			requireGltfReadInView(g, doc, view, gltfUnsigned(g, a, "byteOffset", 0, where), count, element,
								  gltfUnsigned(g, views[std::size_t(view)], "byteStride", 0, where), where);
		else if (count > kMaxGltfUnbackedCount)
			refuse(g.path, where + " has no buffer view and a count of " + std::to_string(count) + " (at most " +
							   std::to_string(kMaxGltfUnbackedCount) + ")");
		if (a.contains("sparse"))
			requireGltfSparse(g, doc, a["sparse"], count, element, where);
	}
}

/// Every primitive's attributes, indices and morph targets name accessors; every node's mesh and skin exist; every
/// scene's nodes exist.
void requireGltfMeshReferences(const GltfContext& g, const Json& doc)
{
	const std::size_t accessors = gltfArray(g, doc, "accessors").size();
	const Json& meshes = gltfArray(g, doc, "meshes");
	for (std::size_t m = 0; m < meshes.size(); ++m)
	{
		const Json empty = Json::array();
		const Json& primitives = meshes[m].is_object() && meshes[m].contains("primitives") ? meshes[m]["primitives"] : empty;
		for (std::size_t p = 0; p < primitives.size(); ++p)
		{
			const std::string where = gltfWhere("meshes", m) + ".primitives[" + std::to_string(p) + "]";
			gltfIndex(g, primitives[p], "indices", accessors, "accessors", where, false);
			std::vector<std::pair<std::string, const Json*>> sets = {{"attributes", nullptr}};
			if (primitives[p].is_object() && primitives[p].contains("attributes"))
				sets[0].second = &primitives[p]["attributes"];
			if (primitives[p].is_object() && primitives[p].contains("targets") && primitives[p]["targets"].is_array())
				for (std::size_t t = 0; t < primitives[p]["targets"].size(); ++t)
					sets.push_back({"targets[" + std::to_string(t) + "]", &primitives[p]["targets"][t]});
			for (const auto& [name, set] : sets)
				if (set != nullptr && set->is_object())
					for (auto it = set->begin(); it != set->end(); ++it)
						gltfIndex(g, *set, it.key().c_str(), accessors, "accessors", where + "." + name, true);
		}
	}
	const Json& nodes = gltfArray(g, doc, "nodes");
	for (std::size_t n = 0; n < nodes.size(); ++n)
	{
		gltfIndex(g, nodes[n], "mesh", meshes.size(), "meshes", gltfWhere("nodes", n), false);
		gltfIndex(g, nodes[n], "skin", gltfArray(g, doc, "skins").size(), "skins", gltfWhere("nodes", n), false);
	}
	const Json& scenes = gltfArray(g, doc, "scenes");
	for (std::size_t s = 0; s < scenes.size(); ++s)
		if (scenes[s].is_object() && scenes[s].contains("nodes") && scenes[s]["nodes"].is_array())
			for (std::size_t k = 0; k < scenes[s]["nodes"].size(); ++k)
				gltfIndexValue(g, scenes[s]["nodes"][k], nodes.size(), "nodes",
							   gltfWhere("scenes", s) + ".nodes[" + std::to_string(k) + "]");
	gltfIndex(g, doc, "scene", scenes.size(), "scenes", "glTF", false);
}

/// The accessor `index` has type `type`, float components and at least `count` elements.
void requireGltfAccessorShape(const GltfContext& g, const Json& doc, long long index, const char* type,
							  std::uint64_t count, const std::string& where)
{
	const Json& a = doc["accessors"][std::size_t(index)];
	const std::string what = where + " (accessor " + std::to_string(index) + ")";
	if (a["type"] != type || gltfUnsigned(g, a, "componentType", 0, what) != 5126)
		refuse(g.path, what + " is not a float " + type);
	if (gltfUnsigned(g, a, "count", 0, what) < count)
		refuse(g.path, what + " has " + a["count"].dump() + " elements, fewer than " + std::to_string(count));
}

/// Every skin names existing joint nodes (at least one) and float MAT4 inverse bind matrices, one per joint.
/// glTF 2.0 makes inverseBindMatrices optional, but assimp 5.2's glTF2 reader dereferences it unconditionally
/// (the crash of tests/data/robust_fuzz_glb_skin_no_ibm.glb), so a skin without it is refused here.
void requireGltfSkins(const GltfContext& g, const Json& doc)
{
	const Json& skins = gltfArray(g, doc, "skins");
	const std::size_t nodes = gltfArray(g, doc, "nodes").size();
	const std::size_t accessors = gltfArray(g, doc, "accessors").size();
	for (std::size_t s = 0; s < skins.size(); ++s)
	{
		const std::string where = gltfWhere("skins", s);
		if (!skins[s].is_object() || !skins[s].contains("joints") || !skins[s]["joints"].is_array() ||
			skins[s]["joints"].empty())
			refuse(g.path, where + " has no joints");
		const Json& joints = skins[s]["joints"];
		for (std::size_t j = 0; j < joints.size(); ++j)
			gltfIndexValue(g, joints[j], nodes, "nodes", where + ".joints[" + std::to_string(j) + "]");
		gltfIndex(g, skins[s], "skeleton", nodes, "nodes", where, false);
		if (!skins[s].contains("inverseBindMatrices"))
			refuse(g.path, where + " has no inverseBindMatrices (optional in glTF 2.0, but assimp 5.2 cannot read a "
								   "skin without them)");
		const long long ibm = gltfIndex(g, skins[s], "inverseBindMatrices", accessors, "accessors", where, true);
		requireGltfAccessorShape(g, doc, ibm, "MAT4", joints.size(), where + ".inverseBindMatrices");
	}
}

/// Every animation channel names an existing sampler and node; every sampler's input (float SCALAR key times)
/// and output accessors exist.
void requireGltfAnimations(const GltfContext& g, const Json& doc)
{
	const Json& animations = gltfArray(g, doc, "animations");
	const std::size_t nodes = gltfArray(g, doc, "nodes").size();
	const std::size_t accessors = gltfArray(g, doc, "accessors").size();
	for (std::size_t a = 0; a < animations.size(); ++a)
	{
		const std::string where = gltfWhere("animations", a);
		const Json& samplers = gltfArray(g, animations[a], "samplers");
		for (std::size_t s = 0; s < samplers.size(); ++s)
		{
			const std::string at = where + ".samplers[" + std::to_string(s) + "]";
			const long long input = gltfIndex(g, samplers[s], "input", accessors, "accessors", at, true);
			gltfIndex(g, samplers[s], "output", accessors, "accessors", at, true);
			requireGltfAccessorShape(g, doc, input, "SCALAR", 1, at + ".input");
		}
		const Json& channels = gltfArray(g, animations[a], "channels");
		for (std::size_t c = 0; c < channels.size(); ++c)
		{
			const std::string at = where + ".channels[" + std::to_string(c) + "]";
			gltfIndex(g, channels[c], "sampler", samplers.size(), "samplers", at, true);
			if (channels[c].is_object() && channels[c].contains("target"))
				gltfIndex(g, channels[c]["target"], "node", nodes, "nodes", at + ".target", false);
		}
	}
}

/// A glTF 2.0 document's references (see above). glTF 1.0 names objects by key; it is left to the other checks.
/// assimp reads a document without asset.version as glTF 2.0 (a skin without inverseBindMatrices in such a file
/// crashed it), so only a version string starting with "1" skips these checks.
void requireGltfReferences(const GltfContext& g, const Json& doc)
{
	const bool v1 = doc.contains("asset") && doc["asset"].is_object() && doc["asset"].contains("version") &&
					doc["asset"]["version"].is_string() && doc["asset"]["version"].get<std::string>().rfind("1", 0) == 0;
	if (v1)
		return;
	requireGltfBufferViews(g, doc);
	requireGltfAccessors(g, doc);
	requireGltfMeshReferences(g, doc);
	requireGltfSkins(g, doc);
	requireGltfAnimations(g, doc);
}

/// A SAX pass over JSON text that notes the first key repeated within one object and the first parse error. It keeps
/// one key set per open object and nothing else (a DOM parse with a per-key callback took over 20 s on a 450 KB
/// fuzzed glTF under ASan; this pass takes well under a second).
struct RepeatedKeyFinder : nlohmann::json_sax<Json>
{
	std::vector<std::set<std::string>> keysOfOpenObjects;
	std::string repeated;
	std::string parseError;

	bool null() override { return true; }
	bool boolean(bool) override { return true; }
	bool number_integer(number_integer_t) override { return true; }
	bool number_unsigned(number_unsigned_t) override { return true; }
	bool number_float(number_float_t, const string_t&) override { return true; }
	bool string(string_t&) override { return true; }
	bool binary(binary_t&) override { return true; }
	bool start_object(std::size_t) override
	{
		keysOfOpenObjects.emplace_back();
		return true;
	}
	bool key(string_t& k) override
	{
		if (!keysOfOpenObjects.back().insert(k).second && repeated.empty())
			repeated = k;
		return true;
	}
	bool end_object() override
	{
		keysOfOpenObjects.pop_back();
		return true;
	}
	bool start_array(std::size_t) override { return true; }
	bool end_array() override { return true; }
	bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) override
	{
		parseError = e.what();
		return false;
	}
};

/// The JSON text of a glTF file, parsed as assimp's reader (rapidjson) parses it, or refused where the two parsers
/// could disagree: these checks must see the document assimp reads. Both stop at a NUL byte. rapidjson does not
/// validate UTF-8 and keeps the first of two equal keys where nlohmann keeps the last, so text nlohmann cannot
/// parse, and any object with a repeated key, is refused (a fuzzed GLB with one invalid UTF-8 byte, and one with a
/// second "skins" array, reached assimp unchecked and crashed it: tests/data/robust_gltf_*).
/// \throws MeshLoadError naming the parse error or the repeated key.
Json parseGltfJson(const GltfContext& g, const std::string& text)
{
	RepeatedKeyFinder finder;
	Json::sax_parse(text, &finder);
	if (!finder.parseError.empty())
	{
		std::string why = finder.parseError; // quotes the bytes last read: keep the message one printable line
		std::replace_if(why.begin(), why.end(), [](char c) { return (unsigned char)c < 0x20 || (unsigned char)c > 0x7e; }, '?');
		refuse(g.path, "JSON text (read as glTF) does not parse: " + why);
	}
	if (!finder.repeated.empty())
		refuse(g.path, "JSON text (read as glTF) repeats the key \"" + finder.repeated +
						   "\" in one object (readers disagree on which one counts)");
	return Json::parse(text);
}

void requireSafeGltfJson(const GltfContext& g, const std::string& text)
{
	const std::string depth = jsonDepthProblem(text);
	if (!depth.empty())
		refuse(g.path, "JSON text (read as glTF): " + depth);
	const Json doc = parseGltfJson(g, text);
	if (!doc.is_object())
		return; // not a glTF document: assimp decides what the file is
	requireGltfNodeTree(g, doc);
	requireGltfBuffers(g, doc, "buffers", true);
	requireGltfBuffers(g, doc, "images", false);
	requireGltfReferences(g, doc);
}

std::uint32_t le32(const std::string& b, std::size_t at)
{
	return std::uint32_t((unsigned char)b[at]) | std::uint32_t((unsigned char)b[at + 1]) << 8 |
		   std::uint32_t((unsigned char)b[at + 2]) << 16 | std::uint32_t((unsigned char)b[at + 3]) << 24;
}

/// GLB (binary glTF, versions 1 and 2): the header's lengths must fit in the file before anything is read (a
/// 592-byte GLB declaring a 4 GB JSON chunk took assimp 17 s and 4.2 GB), then the JSON chunk is checked as glTF.
void requireSafeGlb(const std::string& path, const std::string& head)
{
	const std::uint64_t size = fileSize(path);
	if (head.size() < 20)
		refuse(path, "GLB file shorter than its 20-byte header");
	const std::uint32_t version = le32(head, 4), total = le32(head, 8), jsonBytes = le32(head, 12);
	if (version != 1 && version != 2)
		refuse(path, "GLB version " + std::to_string(version) + " (1 or 2 expected)");
	if (total > size)
		refuse(path, "GLB header declares " + std::to_string(total) + " bytes but the file has " + std::to_string(size));
	if (std::uint64_t(jsonBytes) + 20 > total || jsonBytes > kMaxGltfJsonBytes)
		refuse(path, "GLB header declares a JSON chunk of " + std::to_string(jsonBytes) + " bytes in a file of " +
						 std::to_string(total));
	if (version == 2 && le32(head, 16) != 0x4E4F534Au) // "JSON"
		refuse(path, "GLB first chunk is not JSON");
	GltfContext g{path, true, 0};
	// Version 2 pads the JSON chunk to 4 bytes; version 1's body follows its JSON directly.
	const std::uint64_t afterJson = 20 + (version == 2 ? (std::uint64_t(jsonBytes) + 3) / 4 * 4 : jsonBytes);
	if (version == 1)
		g.binChunkBytes = total - afterJson;
	else if (afterJson + 8 <= total)
	{
		const std::string chunk = readBytes(path, afterJson, 8);
		const std::uint32_t binBytes = chunk.size() == 8 ? le32(chunk, 0) : 0;
		if (afterJson + 8 + binBytes > total)
			refuse(path, "GLB binary chunk of " + std::to_string(binBytes) + " bytes runs past the end of the file");
		g.binChunkBytes = binBytes;
	}
	requireSafeGltfJson(g, readBytes(path, 20, jsonBytes));
}

// --- OBJ -----------------------------------------------------------------------------------------------------

/// Every material library named (and assimp's fallback, the OBJ's own name with .mtl) is a regular file when it
/// exists (a FIFO blocks assimp's open); bounded object, group and material statements (kMaxObjMeshStatements).
void requireSafeObj(const std::string& path)
{
	std::ifstream in(path, std::ios::binary);
	std::string line;
	int statements = 0;
	std::set<std::string> materials;
	bool namesLibrary = false;
	while (std::getline(in, line))
	{
		const std::size_t start = line.find_first_not_of(" \t");
		if (start == std::string::npos || !std::strchr("omgu", line[start]))
			continue; // most lines: v, vt, vn, f, #
		const std::vector<std::string> tok = tokens(line.substr(start));
		const std::string& key = tok[0];
		if (key == "o" || key == "g" || key == "usemtl")
			if (++statements > kMaxObjMeshStatements)
				refuse(path, "OBJ has more than " + std::to_string(kMaxObjMeshStatements) +
								 " object/group/material statements (o, g, usemtl)");
		if (key == "usemtl" && tok.size() > 1 && materials.insert(tok[1]).second &&
			int(materials.size()) > kMaxObjMaterials)
			refuse(path, "OBJ uses more than " + std::to_string(kMaxObjMaterials) + " distinct materials");
		if (key != "mtllib" || tok.size() < 2)
			continue;
		namesLibrary = true;
		std::string rest = line.substr(line.find("mtllib", start) + 6);
		rest.erase(0, rest.find_first_not_of(" \t"));
		rest.erase(rest.find_last_not_of(" \t\r") + 1);
		std::vector<std::string> names(tok.begin() + 1, tok.end());
		names.push_back(rest); // assimp 5.2 takes the rest of the line as one name
		for (const std::string& name : names)
		{
			const std::string problem = referencedProblem(path, name, false);
			if (!problem.empty())
				refuse(path, "OBJ mtllib names " + problem);
		}
	}
	if (namesLibrary && path.size() > 3)
	{
		const std::string fallback = path.substr(0, path.size() - 3) + "mtl";
		const std::string problem = inputFileProblem(fallback);
		if (!problem.empty() && problem.rfind("does not exist", 0) != 0)
			refuse(path, "OBJ material fallback '" + fallback + "' " + problem);
	}
}

} // namespace

void requireSafeMeshFile(const std::string& path)
{
	const std::string head = readBytes(path, 0, 65536);
	if (head.compare(0, 3, "ply") == 0)
	{
		const PlyHeader header = readPlyHeader(path, head);
		requirePlyCountsFit(path, header);
		requirePlyListsFit(path, header);
		if (header.ascii)
			requirePlyAsciiNumbersBounded(path, header);
		return;
	}
	if (head.compare(0, 4, "glTF") == 0)
	{
		requireSafeGlb(path, head);
		return;
	}
	const std::size_t first = head.find_first_not_of(" \t\r\n");
	const bool bom = head.compare(0, 3, "\xEF\xBB\xBF") == 0;
	if ((first != std::string::npos && head[first] == '{') || (bom && head.find('{') == 3))
	{
		const std::uint64_t size = fileSize(path);
		if (size > kMaxGltfJsonBytes)
			refuse(path, "JSON (glTF) file larger than " + std::to_string(kMaxGltfJsonBytes >> 20) + " MiB");
		requireSafeGltfJson(GltfContext{path, false, 0}, readBytes(path, 0, size));
		return;
	}
	requireSafeObj(path);
}

} // namespace bodyfit
