#pragma once
/// \file offscreen_renderer.h
/// Headless picture of a drape result: OpenGL 1.x fixed-function pipeline through OSMesa (Mesa's software
/// rasteriser, no display, no GPU), two orthographic views side by side (front from +z, side from +x), Lambert +
/// specular lighting from two lights, 2x2 supersampling, written as PNG with libpng.

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace bodyfit::render
{

/// One triangle mesh to draw, in world coordinates (metres, +y up).
struct DrawMesh
{
	Eigen::MatrixX3d V;                           ///< #V by 3 vertex positions
	Eigen::MatrixX3i F;                           ///< #F by 3 triangles (CCW seen from outside)
	Eigen::Vector3f color{0.8f, 0.8f, 0.8f};      ///< diffuse RGB, 0..1
	bool twoSided = false;                        ///< light both faces (cloth); one-sided faces are culled at the back
};

/// An 8-bit RGB image, rows top to bottom.
struct Image
{
	int width = 0;
	int height = 0;
	std::vector<std::uint8_t> rgb; ///< width * height * 3 bytes

	std::uint8_t at(int x, int y, int channel) const { return rgb[(std::size_t(y) * width + x) * 3 + channel]; }
};

struct RenderOptions
{
	int width = 1200;                              ///< whole image (both views), pixels
	int height = 900;
	Eigen::Vector3f background{1.0f, 1.0f, 1.0f};
	int supersample = 2;                           ///< render at N times the size and box-filter down (1 = off)
	double paddingFraction = 0.06;                 ///< free border around the scene's bounding box in each view
	double elevationDeg = 15.0;                    ///< both cameras look down by this angle (orthographic)
	/// Close-up: when zoomHalfSize > 0, each view frames the square of that half size (metres) around zoomCenter
	/// (world) instead of every vertex; geometry outside it is cut off.
	Eigen::Vector3d zoomCenter = Eigen::Vector3d::Zero();
	double zoomHalfSize = 0.0;
};

/// Renders the meshes twice (front view from +z, side view from +x, both tilted down by `elevationDeg`), framing
/// all vertices (or the close-up square of RenderOptions) with the same scale (pixels per metre) in both views.
/// \throws std::runtime_error if OSMesa cannot create a context or the size is not in 1..8192.
Image renderTwoViews(const std::vector<DrawMesh>& meshes, const RenderOptions& options = {});

/// Writes an 8-bit RGB PNG. \throws std::runtime_error naming the path when the file cannot be written.
void writePng(const std::string& path, const Image& image);

/// Triangulated ellipsoid surface (UV sphere mapped through centre + rotation * diag(radii)).
DrawMesh ellipsoidMesh(const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& radii,
					   int slices = 24, int stacks = 12);

} // namespace bodyfit::render
