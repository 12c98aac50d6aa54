#pragma once
/// \file errors.h
/// Typed exceptions thrown at the edges of the library (file input, user-supplied data).
/// Each message is one line that names what is wrong (and the file, when there is one).

#include <stdexcept>
#include <string>

namespace bodyfit
{

/// A mesh file is missing, unreadable, empty, truncated or in an unsupported format.
class MeshLoadError : public std::runtime_error
{
public:
	using std::runtime_error::runtime_error;
};

/// Data was read but cannot be used: non-finite coordinates, too few distinct points, zero faces, ...
class InvalidInputError : public std::runtime_error
{
public:
	using std::runtime_error::runtime_error;
};

/// A JSON document (ellipsoid set, scene) is malformed or has a bad field; the message names the field.
class FormatError : public std::runtime_error
{
public:
	using std::runtime_error::runtime_error;
};

} // namespace bodyfit
