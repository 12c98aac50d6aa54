// The skin field's side file: layout in skin_field.h.
#include "bodyfit/fitting/skin_field.h"

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"
#include "bodyfit/fitting/input_files.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <type_traits>

namespace bodyfit
{

namespace
{

constexpr std::size_t kHeaderBytes = 96;
constexpr std::size_t kChecksumBytes = 8;

std::uint64_t fnv1a(const char* data, std::size_t n)
{
	std::uint64_t h = 14695981039346656037ULL;
	for (std::size_t i = 0; i < n; ++i)
	{
		h ^= std::uint8_t(data[i]);
		h *= 1099511628211ULL;
	}
	return h;
}

/// The unsigned integer of T's size (T: a fixed-width integer or double).
template <class T>
using Bits = std::conditional_t<sizeof(T) == 8, std::uint64_t,
								std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint16_t>>;

/// Little-endian writer (bytes by shifts, whatever the host's order).
class Writer
{
public:
	template <class T>
	void put(T value)
	{
		Bits<T> bits;
		std::memcpy(&bits, &value, sizeof(T));
		for (std::size_t i = 0; i < sizeof(T); ++i)
			out_.push_back(char(std::uint8_t(bits >> (8 * i))));
	}
	std::string& bytes() { return out_; }

private:
	std::string out_;
};

/// Little-endian reader over bytes whose length has been checked.
class Cursor
{
public:
	explicit Cursor(const std::string& bytes) : bytes_(bytes) {}
	template <class T>
	T get()
	{
		Bits<T> bits = 0;
		for (std::size_t i = 0; i < sizeof(T); ++i)
			bits = Bits<T>(bits | Bits<T>(Bits<T>(std::uint8_t(bytes_[at_ + i])) << (8 * i)));
		at_ += sizeof(T);
		T value;
		std::memcpy(&value, &bits, sizeof(T));
		return value;
	}
	void seek(std::size_t at) { at_ = at; }

private:
	const std::string& bytes_;
	std::size_t at_ = 0;
};

std::string number(double v)
{
	std::ostringstream s;
	s.precision(6);
	s << v;
	return s.str();
}

/// Header values in the range a bake produces, "" or the problem.
std::string headerProblem(const SkinField& f, long long stored, long long lowered)
{
	for (int k = 0; k < 3; ++k)
		if (!(std::abs(f.origin[k]) <= kMaxFitCoordinate))
			return "origin[" + std::to_string(k) + "] must be finite and within " + number(kMaxFitCoordinate) +
				   " m (got " + number(f.origin[k]) + ")";
	SkinFieldOptions o;
	o.voxel = f.voxel, o.clamp = f.clamp, o.skinOffset = f.skinOffset;
	try
	{
		validateSkinFieldOptions(o);
	}
	catch (const InvalidInputError& e)
	{
		return std::string(e.what()).substr(std::strlen("skin field: "));
	}
	if (!(f.maxError >= 0.0 && f.maxError <= 1.0))
		return "max error must be in [0, 1] m (got " + number(f.maxError) + ")";
	const std::string dims = std::to_string(f.nx) + " x " + std::to_string(f.ny) + " x " + std::to_string(f.nz);
	if (f.nx < 1 || f.ny < 1 || f.nz < 1)
		return "brick dimensions must be >= 1 (got " + dims + ")";
	long long bricks = 1;
	for (int n : {f.nx, f.ny, f.nz}) // each factor and running product <= the limit: no overflow
		if ((bricks *= n) > kMaxSkinFieldBricks)
			return "grid of " + dims + " bricks exceeds the limit of " + std::to_string(kMaxSkinFieldBricks) + " bricks";
	if (stored < 0 || stored > bricks)
		return "stored bricks " + std::to_string(stored) + " not in [0, " + std::to_string(bricks) + "]";
	if (lowered < 0)
		return "lowered samples must be >= 0 (got " + std::to_string(lowered) + ")";
	return "";
}

/// Every index entry -2, -1 or a block used exactly once; every sample in [-32767, 32767]. "" or the problem.
std::string contentProblem(const SkinField& f)
{
	std::vector<char> used(std::size_t(f.storedBricks()), 0);
	for (std::size_t i = 0; i < f.brickIndex.size(); ++i)
	{
		const std::int32_t s = f.brickIndex[i];
		if (s < kFarInside || s >= f.storedBricks())
			return "brick index[" + std::to_string(i) + "] = " + std::to_string(s) + " is out of range [-2, " +
				   std::to_string(f.storedBricks() - 1) + "]";
		if (s >= 0 && used[std::size_t(s)]++)
			return "brick index[" + std::to_string(i) + "]: block " + std::to_string(s) + " is used twice";
	}
	for (std::size_t b = 0; b < used.size(); ++b)
		if (!used[b])
			return "block " + std::to_string(b) + " is stored but no brick uses it";
	for (std::size_t i = 0; i < f.samples.size(); ++i)
		if (f.samples[i] < -32767)
			return "sample " + std::to_string(i) + " is -32768 (quanta are in [-32767, 32767])";
	return "";
}

} // namespace

std::string skinFieldBytes(const SkinField& f)
{
	Writer w;
	w.bytes().append(kSkinFieldMagic, sizeof kSkinFieldMagic);
	w.put<std::uint32_t>(kSkinFieldFileVersion);
	w.put<std::uint32_t>(std::uint32_t(kSkinBrickEdge));
	for (double v : {f.origin.x(), f.origin.y(), f.origin.z(), f.voxel, f.clamp, f.skinOffset, f.maxError})
		w.put<double>(v);
	for (std::int32_t v : {std::int32_t(f.nx), std::int32_t(f.ny), std::int32_t(f.nz), std::int32_t(f.storedBricks()),
						   std::int32_t(f.loweredSamples)})
		w.put<std::int32_t>(v);
	w.put<std::uint32_t>(0);
	for (std::int32_t v : f.brickIndex)
		w.put<std::int32_t>(v);
	for (std::int16_t v : f.samples)
		w.put<std::int16_t>(v);
	w.put<std::uint64_t>(fnv1a(w.bytes().data(), w.bytes().size()));
	return std::move(w.bytes());
}

SkinField parseSkinField(const std::string& bytes, const std::string& name)
{
	auto fail = [&](const std::string& problem) { throw FormatError(name + ": skin field: " + problem); };
	if (bytes.size() < kHeaderBytes + kChecksumBytes)
		fail("truncated (" + std::to_string(bytes.size()) + " bytes; the header alone is " +
			 std::to_string(kHeaderBytes + kChecksumBytes) + ")");
	if (std::memcmp(bytes.data(), kSkinFieldMagic, sizeof kSkinFieldMagic) != 0)
		fail("bad magic (not a bodyfit skin field file)");
	Cursor in(bytes);
	in.get<std::uint64_t>();
	const std::uint32_t version = in.get<std::uint32_t>();
	if (version != kSkinFieldFileVersion)
		fail("unsupported version " + std::to_string(version) + " (this build reads version " +
			 std::to_string(kSkinFieldFileVersion) + ")");
	const std::uint32_t edge = in.get<std::uint32_t>();
	if (edge != std::uint32_t(kSkinBrickEdge))
		fail("brick edge " + std::to_string(edge) + " (the layout has " + std::to_string(kSkinBrickEdge) + ")");
	SkinField f;
	for (int k = 0; k < 3; ++k)
		f.origin[k] = in.get<double>();
	f.voxel = in.get<double>(), f.clamp = in.get<double>(), f.skinOffset = in.get<double>(), f.maxError = in.get<double>();
	f.nx = in.get<std::int32_t>(), f.ny = in.get<std::int32_t>(), f.nz = in.get<std::int32_t>();
	const long long stored = in.get<std::int32_t>(), lowered = in.get<std::int32_t>();
	in.get<std::uint32_t>();
	if (const std::string problem = headerProblem(f, stored, lowered); !problem.empty())
		fail(problem);
	f.loweredSamples = int(lowered);
	// Sizes against the length before anything is allocated (the header cannot ask for gigabytes).
	const std::size_t bricks = std::size_t(f.nx) * std::size_t(f.ny) * std::size_t(f.nz);
	const std::size_t expected =
		kHeaderBytes + 4 * bricks + 2 * std::size_t(stored) * std::size_t(kSkinBrickSamples) + kChecksumBytes;
	if (bytes.size() != expected)
		fail((bytes.size() < expected ? "truncated: " : "trailing bytes: ") + std::to_string(bytes.size()) +
			 " bytes, the header describes " + std::to_string(expected));
	in.seek(expected - kChecksumBytes);
	if (in.get<std::uint64_t>() != fnv1a(bytes.data(), expected - kChecksumBytes))
		fail("checksum mismatch (the file is corrupt)");
	in.seek(kHeaderBytes);
	f.brickIndex.resize(bricks);
	f.samples.resize(std::size_t(stored) * std::size_t(kSkinBrickSamples));
	for (std::int32_t& v : f.brickIndex)
		v = in.get<std::int32_t>();
	for (std::int16_t& v : f.samples)
		v = in.get<std::int16_t>();
	if (const std::string problem = contentProblem(f); !problem.empty())
		fail(problem);
	return f;
}

void writeSkinField(const std::string& path, const SkinField& field)
{
	const std::string bytes = skinFieldBytes(field);
	std::ofstream out(path, std::ios::binary);
	if (!out)
		throw FormatError(path + ": cannot open for writing");
	out.write(bytes.data(), std::streamsize(bytes.size()));
	out.close();
	if (!out)
		throw FormatError(path + ": write failed");
}

SkinField readSkinField(const std::string& path)
{
	const std::string problem = inputFileProblem(path);
	if (!problem.empty())
		throw FormatError(path + ": cannot open skin field file: " + problem);
	std::ifstream in(path, std::ios::binary);
	if (!in)
		throw FormatError(path + ": cannot open skin field file");
	in.seekg(0, std::ios::end);
	const std::streamoff size = in.tellg();
	in.seekg(0, std::ios::beg);
	if (size < 0 || std::size_t(size) > kMaxSkinFieldFileBytes)
		throw FormatError(path + ": skin field: file is larger than " + std::to_string(kMaxSkinFieldFileBytes >> 20) +
						  " MiB (" + std::to_string(size) + " bytes)");
	std::string bytes(std::size_t(size), '\0');
	if (size > 0 && !in.read(&bytes[0], size))
		throw FormatError(path + ": read failed");
	return parseSkinField(bytes, path);
}

} // namespace bodyfit
