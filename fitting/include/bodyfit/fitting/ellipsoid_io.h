#pragma once
/// \file ellipsoid_io.h
/// The ellipsoid-set JSON file of docs/DESIGN.md sec. 6 ("format": "bodyfit.ellipsoids", "version": 1), read and
/// written, and export of the ellipsoids as a triangle mesh for viewers.
///
/// Written fields: format, version, units ("m"), up ("+y"), source {mesh, vertices, height},
/// params {mu_torso, mu_limbs, relative_to_height, sigma, max_ellipsoids, min_radius, recluster_group,
/// cover_triangles, cover_spacing},
/// ellipsoids [{region, center [x,y,z], rotation [w,x,y,z] (unit quaternion, w >= 0), axes [a,b,c] (semi-axes,
/// metres, along the rotation's x, y, z columns), radial_error, max_radial_error, mean_distance, max_distance,
/// vertices}], timing_ms {stage: ms, ...}, stats {count, mean_radial_error, max_radial_error, mean_distance,
/// max_distance}, refinement {status, splits_accepted, splits_rejected}, warnings [..], and for a fit made on a rig's
/// bind pose the optional skinning section of skinned_fit.h (its own version; a file without it is a static fit), and
/// for a fit with a baked skin field the optional skin_field section {file, version, voxel, clamp, bricks, bytes,
/// max_error}: the side file (skin_field.h) holds the field; the section names it and summarises it. A file without
/// the section has no field (older files load as before).
/// Doubles are written with the shortest representation that parses back to the same double (bit-exact).
///
/// Read: format, version and ellipsoids are required; each ellipsoid needs region, center, rotation and axes. The
/// error fields of an ellipsoid are optional (absent = NaN, "unknown", and omitted again when written back); the
/// other top-level objects are optional and checked when present.

#include "bodyfit/fitting/body_fitter.h"

#include <string>

namespace bodyfit
{

constexpr const char* kEllipsoidFormat = "bodyfit.ellipsoids";
constexpr int kEllipsoidFormatVersion = 1;

/// The geometry a fit file holds (metres): every centre coordinate within kMaxFitCoordinate of the origin, every
/// semi-axis in [kMinFitAxis, kMaxFitAxis]. Bodies are 0.1-3 m; at 1000 m a float (Bullet's btScalar) still has a
/// spacing of 0.06 mm, while 1e39 is no float at all (inf) and 1e-40 rounds to 0. Read and written files are both
/// held to it, so a fit that could not be read back (a millimetre mesh fitted without --scale) is never written.
constexpr double kMaxFitCoordinate = 1000.0;
constexpr double kMinFitAxis = 1e-6;
constexpr double kMaxFitAxis = 1000.0;

/// JSON text of `fit` (2-space indented). The skin_field section is written when fit.skinField is set and
/// fit.skinFieldFile names its side file.
std::string toEllipsoidJson(const BodyFit& fit);

/// Writes toEllipsoidJson(fit) to `path` (the directory must exist) and, when fit.skinField is set, the field to
/// skinFieldPathFor(path), named in the JSON. \throws FormatError, before opening the file, if an ellipsoid is outside
/// the range above (naming it), or if a file cannot be written.
void writeEllipsoidJson(const std::string& path, const BodyFit& fit);

/// Parses and validates an ellipsoid-set document. `name` is used in error messages (usually the file path).
/// \throws FormatError "<name>: <field>: <problem>", e.g. "fit.json: ellipsoids[3].axes[1]: must be > 0 (got -0.01)".
BodyFit parseEllipsoidJson(const std::string& text, const std::string& name = "<json>");

/// Reads and validates a file, and the skin field's side file when the fit file names one (in the same directory).
/// \throws FormatError (also for a missing or unreadable file), naming the file; for the side file
/// "<fit>: skin_field: <side file>: <problem>" (missing, truncated, corrupt, or not matching the section).
BodyFit readEllipsoidJson(const std::string& path);

/// The side file writeEllipsoidJson writes for a fit file: its path with the extension replaced by ".skin"
/// (fit.json -> fit.skin; a name already ending in .skin gets a second one).
std::string skinFieldPathFor(const std::string& fitPath);

/// The ellipsoids as one triangle mesh: a unit icosphere subdivided `subdivisions` times (0 = 20 triangles, each
/// level x4; 2 = 320 triangles, 162 vertices per ellipsoid), mapped by x = c + R diag(axes) u. Optional per-vertex
/// colours (regionColor of segmentation.h) are written into `colors`.
TriMesh ellipsoidMesh(const std::vector<FittedEllipsoid>& ellipsoids, int subdivisions = 2,
					  Eigen::MatrixX3d* colors = nullptr);

/// Writes ellipsoidMesh(...) as OBJ or PLY (by extension, coloured by region) through saveTriMesh.
/// \throws InvalidInputError for another extension, MeshLoadError if the file cannot be written.
void exportEllipsoidMesh(const std::string& path, const std::vector<FittedEllipsoid>& ellipsoids,
						 int subdivisions = 2);

} // namespace bodyfit
