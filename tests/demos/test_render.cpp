// Offscreen renderer (OSMesa) and PNG writer: image size, non-blank content, PNG header, both views drawn.
#include "render/offscreen_renderer.h"

#include <Eigen/Geometry>
#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>
#include <unistd.h>

using namespace bodyfit::render;

namespace
{

/// Pixels (in the column range [x0, x1)) whose colour differs from the white background by more than 8/255 in
/// some channel: anti-aliasing and the separator rule stay below that fraction of the image.
int nonBackground(const Image& im, int x0, int x1)
{
	int n = 0;
	for (int y = 0; y < im.height; ++y)
		for (int x = x0; x < x1; ++x)
			for (int c = 0; c < 3; ++c)
				if (im.at(x, y, c) < 247)
				{
					++n;
					break;
				}
	return n;
}

std::vector<DrawMesh> testScene()
{
	std::vector<DrawMesh> meshes;
	meshes.push_back(ellipsoidMesh(Eigen::Vector3d(0, 1, 0), Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.3, 0.5, 0.15)));
	DrawMesh patch;
	patch.V.resize(4, 3);
	patch.V << -0.5, 1.3, -0.5, 0.5, 1.3, -0.5, 0.5, 1.3, 0.5, -0.5, 1.3, 0.5;
	patch.F.resize(2, 3);
	patch.F << 0, 2, 1, 0, 3, 2;
	patch.twoSided = true;
	patch.color = Eigen::Vector3f(0.2f, 0.4f, 0.8f);
	meshes.push_back(patch);
	return meshes;
}

} // namespace

TEST_CASE("renderTwoViews returns an image of the requested size with content in both views", "[render]")
{
	RenderOptions o;
	o.width = 320;
	o.height = 200;
	const Image im = renderTwoViews(testScene(), o);
	REQUIRE(im.width == 320);
	REQUIRE(im.height == 200);
	REQUIRE(im.rgb.size() == std::size_t(320 * 200 * 3));
	// The scene fills most of each view's height (padding 6%): each half must have a substantial drawn area.
	// 10% of a half-view is far below the ~35% the ellipsoid + patch cover and far above a blank view (0).
	const int half = 160 * 200;
	CHECK(nonBackground(im, 0, 159) > half / 10);
	CHECK(nonBackground(im, 161, 320) > half / 10);
	// The patch is blue: some pixel has blue clearly above red.
	bool blue = false;
	for (int y = 0; y < im.height && !blue; ++y)
		for (int x = 0; x < im.width && !blue; ++x)
			blue = im.at(x, y, 2) > im.at(x, y, 0) + 60;
	CHECK(blue);
}

TEST_CASE("renderTwoViews frames the scene: nothing touches the image border", "[render]")
{
	RenderOptions o;
	o.width = 200;
	o.height = 150;
	const Image im = renderTwoViews(testScene(), o);
	// Padding is 6% of the view: the outermost rows stay background.
	int border = 0;
	for (int x = 0; x < im.width; ++x)
		if (x != im.width / 2)
			border += (im.at(x, 0, 0) < 247) + (im.at(x, im.height - 1, 0) < 247);
	CHECK(border == 0);
}

TEST_CASE("renderTwoViews rejects impossible sizes", "[render]")
{
	RenderOptions o;
	o.width = 0;
	CHECK_THROWS_AS(renderTwoViews(testScene(), o), std::runtime_error);
	o.width = 100;
	o.height = 100000;
	CHECK_THROWS_AS(renderTwoViews(testScene(), o), std::runtime_error);
}

TEST_CASE("writePng writes a valid PNG with the image's size", "[render]")
{
	RenderOptions o;
	o.width = 123;
	o.height = 77;
	const Image im = renderTwoViews(testScene(), o);
	const std::string path = (std::filesystem::temp_directory_path() / ("bodyfit_test_render_" + std::to_string(long(::getpid())) + ".png")).string();
	writePng(path, im);
	std::ifstream in(path, std::ios::binary);
	const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	REQUIRE(bytes.size() > 33);
	const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
	CHECK(std::equal(signature, signature + 8, bytes.begin()));
	// IHDR: width and height are big-endian at bytes 16..23; bit depth 8, colour type 2 (RGB).
	auto be32 = [&](int at) {
		return (unsigned(bytes[at]) << 24) | (unsigned(bytes[at + 1]) << 16) | (unsigned(bytes[at + 2]) << 8) |
			   unsigned(bytes[at + 3]);
	};
	CHECK(be32(16) == 123u);
	CHECK(be32(20) == 77u);
	CHECK(bytes[24] == 8);
	CHECK(bytes[25] == 2);
	std::filesystem::remove(path);
	CHECK_THROWS_AS(writePng("/nonexistent-dir/x.png", im), std::runtime_error);
}

TEST_CASE("ellipsoidMesh lies on the ellipsoid and faces outward", "[render]")
{
	const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
	const Eigen::Vector3d c(0.1, 0.2, 0.3), r(0.3, 0.2, 0.1);
	const DrawMesh m = ellipsoidMesh(c, R, r, 16, 8);
	for (int i = 0; i < m.V.rows(); ++i)
	{
		const Eigen::Vector3d u = r.cwiseInverse().asDiagonal() * (R.transpose() * (m.V.row(i).transpose() - c));
		CHECK(u.norm() == Approx(1.0).epsilon(1e-12)); // on the surface up to rounding
	}
	for (int f = 0; f < m.F.rows(); ++f)
	{
		const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), d = m.V.row(m.F(f, 2));
		const Eigen::Vector3d n = (b - a).cross(d - a);
		CHECK(n.dot((a + b + d) / 3.0 - c) > 0.0); // outward: the centroid direction from the centre
	}
}
