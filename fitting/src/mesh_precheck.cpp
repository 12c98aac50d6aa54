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

void requireSafeGltfJson(const GltfContext& g, const std::string& text)
{
	const std::string depth = jsonDepthProblem(text);
	if (!depth.empty())
		refuse(g.path, "JSON text (read as glTF): " + depth);
	const Json doc = Json::parse(text, nullptr, /*allow_exceptions=*/false);
	if (doc.is_discarded() || !doc.is_object())
		return; // not JSON: assimp decides what the file is
	requireGltfNodeTree(g, doc);
	requireGltfBuffers(g, doc, "buffers", true);
	requireGltfBuffers(g, doc, "images", false);
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
