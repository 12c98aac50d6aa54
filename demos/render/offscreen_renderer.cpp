#include "render/offscreen_renderer.h"

#include <GL/osmesa.h>
#include <GL/gl.h>
#include <png.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>

namespace bodyfit::render
{
namespace
{

/// Area-weighted vertex normals (a zero normal is kept for isolated vertices; GL then lights them with ambient only).
Eigen::MatrixX3f vertexNormals(const DrawMesh& m)
{
	Eigen::MatrixX3f N = Eigen::MatrixX3f::Zero(m.V.rows(), 3);
	for (int f = 0; f < m.F.rows(); ++f)
	{
		const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
		const Eigen::Vector3f n = (b - a).cross(c - a).cast<float>();
		for (int k = 0; k < 3; ++k)
			N.row(m.F(f, k)) += n.transpose();
	}
	for (int i = 0; i < N.rows(); ++i)
	{
		const float len = N.row(i).norm();
		if (len > 0.0f)
			N.row(i) /= len;
	}
	return N;
}

struct OsmesaContext
{
	OSMesaContext ctx = nullptr;
	~OsmesaContext()
	{
		if (ctx)
			OSMesaDestroyContext(ctx);
	}
};

void setupLights()
{
	glMatrixMode(GL_MODELVIEW);
	glLoadIdentity(); // lights are given in eye space: they move with the camera, so both views are lit alike
	const GLfloat key[4] = {-0.45f, 0.65f, 1.0f, 0.0f};
	const GLfloat fill[4] = {0.7f, 0.1f, 0.6f, 0.0f};
	const GLfloat keyDiffuse[4] = {0.75f, 0.75f, 0.75f, 1.0f};
	const GLfloat fillDiffuse[4] = {0.3f, 0.3f, 0.32f, 1.0f};
	const GLfloat spec[4] = {0.25f, 0.25f, 0.25f, 1.0f};
	const GLfloat none[4] = {0.0f, 0.0f, 0.0f, 1.0f};
	const GLfloat ambient[4] = {0.22f, 0.22f, 0.22f, 1.0f};
	glEnable(GL_LIGHTING);
	glEnable(GL_LIGHT0);
	glEnable(GL_LIGHT1);
	glLightfv(GL_LIGHT0, GL_POSITION, key);
	glLightfv(GL_LIGHT0, GL_DIFFUSE, keyDiffuse);
	glLightfv(GL_LIGHT0, GL_SPECULAR, spec);
	glLightfv(GL_LIGHT1, GL_POSITION, fill);
	glLightfv(GL_LIGHT1, GL_DIFFUSE, fillDiffuse);
	glLightfv(GL_LIGHT1, GL_SPECULAR, none);
	glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
	glEnable(GL_NORMALIZE);
	glShadeModel(GL_SMOOTH);
}

void drawMesh(const DrawMesh& m, const Eigen::MatrixX3f& normals)
{
	if (m.F.rows() == 0)
		return;
	// Row-major float copies for the vertex arrays (Eigen's default storage is column-major).
	std::vector<GLfloat> pos(std::size_t(m.V.rows()) * 3), nrm(std::size_t(m.V.rows()) * 3);
	for (int i = 0; i < m.V.rows(); ++i)
		for (int k = 0; k < 3; ++k)
		{
			pos[std::size_t(i) * 3 + k] = GLfloat(m.V(i, k));
			nrm[std::size_t(i) * 3 + k] = normals(i, k);
		}
	std::vector<GLuint> idx(std::size_t(m.F.rows()) * 3);
	for (int f = 0; f < m.F.rows(); ++f)
		for (int k = 0; k < 3; ++k)
			idx[std::size_t(f) * 3 + k] = GLuint(m.F(f, k));

	glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, m.twoSided ? GL_TRUE : GL_FALSE);
	const GLfloat front[4] = {m.color.x(), m.color.y(), m.color.z(), 1.0f};
	// The back of a two-sided surface (inside of a skirt) is drawn a little darker so folds read clearly.
	const GLfloat back[4] = {0.7f * m.color.x(), 0.7f * m.color.y(), 0.7f * m.color.z(), 1.0f};
	const GLfloat spec[4] = {0.3f, 0.3f, 0.3f, 1.0f};
	glMaterialfv(GL_FRONT, GL_AMBIENT_AND_DIFFUSE, front);
	glMaterialfv(GL_BACK, GL_AMBIENT_AND_DIFFUSE, m.twoSided ? back : front);
	glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, spec);
	glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, 24.0f);

	glEnableClientState(GL_VERTEX_ARRAY);
	glEnableClientState(GL_NORMAL_ARRAY);
	glVertexPointer(3, GL_FLOAT, 0, pos.data());
	glNormalPointer(GL_FLOAT, 0, nrm.data());
	glDrawElements(GL_TRIANGLES, GLsizei(idx.size()), GL_UNSIGNED_INT, idx.data());
	glDisableClientState(GL_NORMAL_ARRAY);
	glDisableClientState(GL_VERTEX_ARRAY);
}

} // namespace

namespace
{

/// The rotation of a view: the world turned so the camera looks along -z. Front (0): camera on +z; side (1): camera
/// on +x (world +x towards the viewer, a -90 degree turn about y). Both tilted down by `elevation` (radians) so
/// horizontal cloth is not seen edge-on.
Eigen::Matrix3d viewRotation(int view, double elevation)
{
	return Eigen::AngleAxisd(elevation, Eigen::Vector3d::UnitX()).toRotationMatrix() *
		   Eigen::AngleAxisd(view == 0 ? 0.0 : -0.5 * M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
}

/// The box [lo, hi] of the meshes' finite vertices in a view's rotated frame (+-1 when there are none), its x and y
/// replaced by the close-up square when options.zoomHalfSize > 0 (the depth range still holds every vertex).
void frameView(const std::vector<DrawMesh>& meshes, const Eigen::Matrix3d& rotation, const RenderOptions& options,
			   Eigen::Vector3d& lo, Eigen::Vector3d& hi)
{
	lo.setConstant(std::numeric_limits<double>::max());
	hi = -lo;
	bool any = false;
	for (const DrawMesh& m : meshes)
		for (int i = 0; i < m.V.rows(); ++i)
		{
			const Eigen::Vector3d p = m.V.row(i).transpose();
			if (!p.allFinite())
				continue;
			const Eigen::Vector3d e = rotation * p;
			lo = lo.cwiseMin(e);
			hi = hi.cwiseMax(e);
			any = true;
		}
	if (!any)
	{
		lo.setConstant(-1.0);
		hi.setConstant(1.0);
	}
	if (options.zoomHalfSize > 0.0)
	{
		const Eigen::Vector3d c = rotation * options.zoomCenter;
		for (int k = 0; k < 2; ++k)
		{
			lo[k] = c[k] - options.zoomHalfSize;
			hi[k] = c[k] + options.zoomHalfSize;
		}
	}
}

/// Draws the meshes into one view's half of the buffer: an orthographic camera centred on the view's box, halfW x
/// halfH metres across.
void drawView(int view, int W, int H, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& lo,
			  const Eigen::Vector3d& hi, double halfW, double halfH, const std::vector<DrawMesh>& meshes,
			  const std::vector<Eigen::MatrixX3f>& normals)
{
	const int x0 = view == 0 ? 0 : W / 2;
	const Eigen::Vector3d c = 0.5 * (lo + hi);
	const double depth = 0.5 * (hi.z() - lo.z()) + 1.0;
	glViewport(x0, 0, view == 0 ? W / 2 : W - W / 2, H);
	glMatrixMode(GL_PROJECTION);
	glLoadIdentity();
	glOrtho(c.x() - halfW, c.x() + halfW, c.y() - halfH, c.y() + halfH, -c.z() - depth, -c.z() + depth);
	setupLights();
	glMatrixMode(GL_MODELVIEW);
	GLdouble m[16];
	for (int col = 0; col < 4; ++col)
		for (int row = 0; row < 4; ++row)
			m[col * 4 + row] = (row < 3 && col < 3) ? rotation(row, col) : (row == col ? 1.0 : 0.0);
	glLoadMatrixd(m);
	for (std::size_t k = 0; k < meshes.size(); ++k)
		drawMesh(meshes[k], normals[k]);
}

/// The W x H RGBA buffer (rows bottom-up, as GL writes them) box-filtered down by ss and flipped, with a thin grey
/// rule between the two views.
Image downsample(const std::vector<GLubyte>& buffer, int W, int H, int ss, const RenderOptions& options)
{
	Image image;
	image.width = options.width;
	image.height = options.height;
	image.rgb.assign(std::size_t(image.width) * image.height * 3, 0);
	for (int y = 0; y < image.height; ++y)
		for (int x = 0; x < image.width; ++x)
			for (int ch = 0; ch < 3; ++ch)
			{
				int sum = 0;
				for (int dy = 0; dy < ss; ++dy)
					for (int dx = 0; dx < ss; ++dx)
					{
						const int sy = H - 1 - (y * ss + dy);
						sum += buffer[(std::size_t(sy) * W + (x * ss + dx)) * 4 + ch];
					}
				image.rgb[(std::size_t(y) * image.width + x) * 3 + ch] = std::uint8_t(sum / (ss * ss));
			}
	const int mid = image.width / 2;
	for (int y = 0; y < image.height; ++y)
		for (int ch = 0; ch < 3; ++ch)
			image.rgb[(std::size_t(y) * image.width + mid) * 3 + ch] = 160;
	return image;
}

} // namespace

Image renderTwoViews(const std::vector<DrawMesh>& meshes, const RenderOptions& options)
{
	if (options.width < 2 || options.height < 1 || options.width > 8192 || options.height > 8192)
		throw std::runtime_error("render: image size " + std::to_string(options.width) + "x" +
								 std::to_string(options.height) + " is outside 2..8192 x 1..8192");
	const int ss = std::clamp(options.supersample, 1, 4);
	const int W = options.width * ss, H = options.height * ss;

	OsmesaContext context;
	context.ctx = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
	if (!context.ctx)
		throw std::runtime_error("render: OSMesaCreateContextExt failed (is libosmesa6 installed?)");
	std::vector<GLubyte> buffer(std::size_t(W) * H * 4);
	if (!OSMesaMakeCurrent(context.ctx, buffer.data(), GL_UNSIGNED_BYTE, W, H))
		throw std::runtime_error("render: OSMesaMakeCurrent failed for " + std::to_string(W) + "x" +
								 std::to_string(H));

	Eigen::Matrix3d views[2];
	Eigen::Vector3d lo[2], hi[2];
	for (int view = 0; view < 2; ++view)
	{
		views[view] = viewRotation(view, options.elevationDeg * M_PI / 180.0);
		frameView(meshes, views[view], options, lo[view], hi[view]);
	}
	// Framing: one scale (pixels per metre) for both views so sizes compare across them.
	const double viewW = 0.5 * W, viewH = H;
	const double pad = std::clamp(options.paddingFraction, 0.0, 0.4);
	double pixelsPerMetre = std::numeric_limits<double>::max();
	for (int view = 0; view < 2; ++view)
	{
		const Eigen::Vector3d ext = (hi[view] - lo[view]).cwiseMax(Eigen::Vector3d::Constant(1e-3));
		pixelsPerMetre = std::min({pixelsPerMetre, viewW * (1.0 - 2.0 * pad) / ext.x(), viewH * (1.0 - 2.0 * pad) / ext.y()});
	}
	const double halfW = 0.5 * viewW / pixelsPerMetre, halfH = 0.5 * viewH / pixelsPerMetre;

	std::vector<Eigen::MatrixX3f> normals;
	normals.reserve(meshes.size());
	for (const DrawMesh& m : meshes)
		normals.push_back(vertexNormals(m));

	glClearColor(options.background.x(), options.background.y(), options.background.z(), 1.0f);
	glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
	glEnable(GL_DEPTH_TEST);
	glDisable(GL_CULL_FACE);
	for (int view = 0; view < 2; ++view)
		drawView(view, W, H, views[view], lo[view], hi[view], halfW, halfH, meshes, normals);
	glFinish();
	const GLenum err = glGetError();
	if (err != GL_NO_ERROR)
		throw std::runtime_error("render: OpenGL error " + std::to_string(int(err)));
	return downsample(buffer, W, H, ss, options);
}

void writePng(const std::string& path, const Image& image)
{
	if (image.width <= 0 || image.height <= 0 || image.rgb.size() != std::size_t(image.width) * image.height * 3)
		throw std::runtime_error(path + ": cannot write an empty or inconsistent image");
	std::unique_ptr<FILE, int (*)(FILE*)> file(std::fopen(path.c_str(), "wb"), &std::fclose);
	if (!file)
		throw std::runtime_error(path + ": cannot open for writing");
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
	if (!png)
		throw std::runtime_error(path + ": png_create_write_struct failed");
	png_infop info = png_create_info_struct(png);
	if (!info)
	{
		png_destroy_write_struct(&png, nullptr);
		throw std::runtime_error(path + ": png_create_info_struct failed");
	}
	// libpng reports errors by longjmp; nothing with a destructor is created between setjmp and the writes.
	if (setjmp(png_jmpbuf(png)))
	{
		png_destroy_write_struct(&png, &info);
		throw std::runtime_error(path + ": libpng failed while writing");
	}
	png_init_io(png, file.get());
	png_set_IHDR(png, info, png_uint_32(image.width), png_uint_32(image.height), 8, PNG_COLOR_TYPE_RGB,
				 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	png_write_info(png, info);
	for (int y = 0; y < image.height; ++y)
		png_write_row(png, const_cast<png_bytep>(image.rgb.data() + std::size_t(y) * image.width * 3));
	png_write_end(png, nullptr);
	png_destroy_write_struct(&png, &info);
	if (std::fflush(file.get()) != 0)
		throw std::runtime_error(path + ": write failed");
}

DrawMesh ellipsoidMesh(const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& radii,
					   int slices, int stacks)
{
	slices = std::max(slices, 3);
	stacks = std::max(stacks, 2);
	DrawMesh m;
	const int rows = (stacks - 1) * slices + 2;
	m.V.resize(rows, 3);
	const Eigen::Matrix3d A = rotation * radii.asDiagonal();
	auto put = [&](int i, const Eigen::Vector3d& unit) { m.V.row(i) = (center + A * unit).transpose(); };
	put(0, Eigen::Vector3d(0, 0, 1));
	put(rows - 1, Eigen::Vector3d(0, 0, -1));
	for (int s = 1; s < stacks; ++s)
	{
		const double theta = M_PI * s / stacks;
		for (int k = 0; k < slices; ++k)
		{
			const double phi = 2.0 * M_PI * k / slices;
			put(1 + (s - 1) * slices + k,
				Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)));
		}
	}
	std::vector<Eigen::Vector3i> tris;
	auto ring = [&](int s, int k) { return 1 + (s - 1) * slices + (k % slices); };
	for (int k = 0; k < slices; ++k)
	{
		tris.emplace_back(0, ring(1, k), ring(1, k + 1));
		tris.emplace_back(rows - 1, ring(stacks - 1, k + 1), ring(stacks - 1, k));
		for (int s = 1; s + 1 < stacks; ++s)
		{
			tris.emplace_back(ring(s, k), ring(s + 1, k), ring(s + 1, k + 1));
			tris.emplace_back(ring(s, k), ring(s + 1, k + 1), ring(s, k + 1));
		}
	}
	// A mirror in `rotation * diag(radii)` would flip the winding; keep outward-facing triangles either way.
	const bool flip = A.determinant() < 0.0;
	m.F.resize(int(tris.size()), 3);
	for (std::size_t t = 0; t < tris.size(); ++t)
		m.F.row(int(t)) = flip ? Eigen::RowVector3i(tris[t].x(), tris[t].z(), tris[t].y()) : tris[t].transpose();
	return m;
}

} // namespace bodyfit::render
