/*
bodyfit: the skinned-body driver and the refitted triangle mesh. See btSkinnedBodyDriver.h.
*/

#include "bodyfit/bridge/btSkinnedBodyDriver.h"

#include "bodyfit/fitting/errors.h"

#include "bodyfit/bridge/btEigenConversion.h"
#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btSkinMesh.h"
#include "bodyfit/bullet_ext/btTiming.h"

#include <BulletCollision/CollisionShapes/btBvhTriangleMeshShape.h>
#include <BulletCollision/CollisionShapes/btTriangleIndexVertexArray.h>

#include <algorithm>
#include <chrono>
#include <cmath>

namespace bodyfit
{

double AnimationTiming::clipTime(double simSeconds, double duration) const
{
	const double t = startS + speed * simSeconds;
	if (!loop)
		return std::min(std::max(t, 0.0), duration);
	const double wrapped = std::fmod(t, duration);
	return wrapped < 0.0 ? wrapped + duration : wrapped;
}

// --- btRefitTriangleMesh -----------------------------------------------------------------------------------------

btRefitTriangleMesh::btRefitTriangleMesh(const TriMesh& mesh, double margin)
{
	if (mesh.F.rows() == 0)
		throw InvalidInputError("btRefitTriangleMesh: the mesh has no faces");
	if (mesh.F.minCoeff() < 0 || mesh.F.maxCoeff() >= mesh.V.rows())
		throw InvalidInputError("btRefitTriangleMesh: a face index is outside the " + std::to_string(mesh.V.rows()) +
								" vertices");
	if (!mesh.V.allFinite())
		throw InvalidInputError("btRefitTriangleMesh: a vertex coordinate is NaN or infinite");
	if (!(std::isfinite(margin) && margin >= 0.0))
		throw InvalidInputError("btRefitTriangleMesh: the margin must be a finite number >= 0 (got " +
								std::to_string(margin) + ")");
	m_vertices.resize(std::size_t(mesh.V.rows()) * 3);
	for (int i = 0; i < mesh.V.rows(); ++i)
		for (int k = 0; k < 3; ++k)
			m_vertices[std::size_t(i) * 3 + std::size_t(k)] = btScalar(mesh.V(i, k));
	m_indices.resize(std::size_t(mesh.F.rows()) * 3);
	for (int f = 0; f < mesh.F.rows(); ++f)
		for (int k = 0; k < 3; ++k)
			m_indices[std::size_t(f) * 3 + std::size_t(k)] = mesh.F(f, k);
	m_array = std::make_unique<btTriangleIndexVertexArray>(int(mesh.F.rows()), m_indices.data(), int(3 * sizeof(int)),
														   int(mesh.V.rows()), m_vertices.data(),
														   int(3 * sizeof(btScalar)));
	m_shape = std::make_unique<btBvhTriangleMeshShape>(m_array.get(), true);
	m_shape->setMargin(btScalar(margin));
}

btRefitTriangleMesh::~btRefitTriangleMesh() = default;

void btRefitTriangleMesh::setVertices(const Eigen::MatrixX3d& vertices)
{
	if (std::size_t(vertices.rows()) * 3 != m_vertices.size())
		throw InvalidInputError("btRefitTriangleMesh::setVertices: " + std::to_string(vertices.rows()) +
								" vertices given, the mesh has " + std::to_string(m_vertices.size() / 3));
	// A NaN would reach the tree's quantisation (a float to integer conversion out of range): refused before any
	// vertex is replaced, so the mesh keeps its last pose.
	if (!vertices.allFinite()) // one vectorised pass per pose; the offending row is looked up only to name it
		for (int i = 0; i < vertices.rows(); ++i)
			if (!vertices.row(i).allFinite())
				throw InvalidInputError("btRefitTriangleMesh::setVertices: vertex " + std::to_string(i) +
										" has a NaN or infinite coordinate");
	btVector3 lo(BT_LARGE_FLOAT, BT_LARGE_FLOAT, BT_LARGE_FLOAT), hi = -lo;
	for (int i = 0; i < vertices.rows(); ++i)
	{
		const btVector3 p(btScalar(vertices(i, 0)), btScalar(vertices(i, 1)), btScalar(vertices(i, 2)));
		for (int k = 0; k < 3; ++k)
			m_vertices[std::size_t(i) * 3 + std::size_t(k)] = p[k];
		lo.setMin(p);
		hi.setMax(p);
	}
	// The quantized tree is requantized over these bounds; a margin keeps every vertex strictly inside.
	const btVector3 pad(btScalar(1e-3), btScalar(1e-3), btScalar(1e-3));
	btVector3 aabbMin = lo - pad, aabbMax = hi + pad;
	m_shape->refitTree(aabbMin, aabbMax);
}

// --- btSkinnedBodyDriver -----------------------------------------------------------------------------------------

btSkinnedBodyDriver::btSkinnedBodyDriver(const Rig& rig, const BodyFit& fit, const SkinBinding& binding,
										 const AnimationClip& clip, const AnimationTiming& timing,
										 const SkinnedBodyOptions& options)
	: m_clip(&clip), m_timing(timing)
{
	if (!(timing.speed > 0.0) || !std::isfinite(timing.speed))
		throw InvalidInputError("animation speed must be a finite number > 0 (got " + std::to_string(timing.speed) +
								")");
	if (!(timing.startS >= 0.0 && timing.startS <= clip.duration))
		throw InvalidInputError("animation start " + std::to_string(timing.startS) + " s is outside clip '" +
								clip.name + "' (0 .. " + std::to_string(clip.duration) + " s)");
	m_body = std::make_unique<SkinnedBody>(rig, fit, binding, options);
	m_clipTime = m_timing.clipTime(0.0, clip.duration);
	m_body->pose(clip, m_clipTime);
}

btSkinnedBodyDriver::~btSkinnedBodyDriver()
{
	if (m_compound && m_skinMesh && m_compound->getSkinMesh() == m_skinMesh.get())
		m_compound->setSkinMesh(0);
}

void btSkinnedBodyDriver::setCompound(btEllipsoidCompoundShape* compound)
{
	if (compound && compound->getNumEllipsoids() != int(m_body->ellipsoids().size()))
		throw InvalidInputError("btSkinnedBodyDriver: the compound has " + std::to_string(compound->getNumEllipsoids()) +
								" ellipsoids, the skinned fit " + std::to_string(m_body->ellipsoids().size()));
	if (m_compound && m_skinMesh && m_compound->getSkinMesh() == m_skinMesh.get())
		m_compound->setSkinMesh(0);
	m_compound = compound;
	const bool skinMesh = m_skinMeshEnabled && compound && compound->getBindPose() && compound->getSkinField();
	if (skinMesh && !m_skinMesh)
	{
		const TriMesh& bind = m_body->rig().bindMesh;
		std::vector<int> triangles(std::size_t(bind.F.rows()) * 3);
		for (int f = 0; f < bind.F.rows(); ++f)
			for (int k = 0; k < 3; ++k)
				triangles[std::size_t(f) * 3 + std::size_t(k)] = bind.F(f, k);
		btAlignedObjectArray<btVector3> vertices;
		vertices.resize(int(bind.V.rows()));
		for (int i = 0; i < bind.V.rows(); ++i)
			vertices[i] = toBt(Eigen::Vector3d(bind.V.row(i).transpose()));
		auto mesh = std::make_unique<btSkinMesh>();
		const char* why = 0;
		if (!mesh->setTopology(int(bind.V.rows()), triangles.data(), int(bind.F.rows()), &vertices[0], &why))
			throw InvalidInputError(std::string("btSkinnedBodyDriver: ") + why);
		m_skinMesh = std::move(mesh);
	}
	if (skinMesh)
		compound->setSkinMesh(m_skinMesh.get());
	writeCompound();
}

void btSkinnedBodyDriver::setMesh(btRefitTriangleMesh* mesh)
{
	if (mesh && mesh->vertexCount() != int(m_body->vertices().rows()))
		throw InvalidInputError("btSkinnedBodyDriver: the triangle mesh has " + std::to_string(mesh->vertexCount()) +
								" vertices, the skinned body " + std::to_string(m_body->vertices().rows()));
	m_mesh = mesh;
	m_stats.lastMeshSeconds = 0.0;
	writeMesh();
}

void btSkinnedBodyDriver::update(double simSeconds)
{
	if (!std::isfinite(simSeconds)) // a NaN time posed the body at an arbitrary key, an infinite one NaN in a loop
		throw InvalidInputError("btSkinnedBodyDriver::update: the simulation time must be finite (got " +
								std::to_string(simSeconds) + ")");
	if (simSeconds == m_time && m_stats.updates > 0)
		return;
	m_time = simSeconds;
	m_clipTime = m_timing.clipTime(simSeconds, m_clip->duration);
	const auto t0 = std::chrono::steady_clock::now();
	m_body->pose(*m_clip, m_clipTime);
	m_stats.lastBodySeconds = btSecondsSince(t0);
	m_stats.bodySeconds += m_stats.lastBodySeconds;
	writeCompound();
	writeMesh();
	++m_stats.updates;
	++m_revision;
}

void btSkinnedBodyDriver::writeCompound()
{
	m_stats.lastCompoundSeconds = 0.0;
	m_stats.lastMeshSeconds = 0.0; // (the skin mesh here, the triangle mesh in writeMesh)
	if (!m_compound)
		return;
	const auto t0 = std::chrono::steady_clock::now();
	const std::vector<Ellipsoid>& ellipsoids = m_body->ellipsoids();
	const int n = int(ellipsoids.size());
	m_centers.resize(n);
	m_bases.resize(n);
	m_semiAxes.resize(n);
	for (int i = 0; i < n; ++i)
	{
		const Ellipsoid& e = ellipsoids[std::size_t(i)];
		m_centers[i] = toBt(e.center);
		m_bases[i] = toBt(e.rotation);
		m_semiAxes[i] = toBt(e.radii);
	}
	// One pass and one revision bump: the collider sees the whole pose change as one motion of every ellipsoid.
	const char* why = 0;
	if (n > 0 && !m_compound->setEllipsoids(n, &m_centers[0], &m_bases[0], &m_semiAxes[0], &why))
		throw InvalidInputError(std::string("btSkinnedBodyDriver: ") + why);
	if (n > 0 && m_compound->getBindPose())
		writeBoneFrames();
	m_stats.lastCompoundSeconds = btSecondsSince(t0);
	m_stats.compoundSeconds += m_stats.lastCompoundSeconds;
	if (m_skinMesh && m_compound->getSkinMesh() == m_skinMesh.get())
		writeSkinMesh();
}

void btSkinnedBodyDriver::writeSkinMesh()
{
	const auto t0 = std::chrono::steady_clock::now();
	const Eigen::MatrixX3d& v = m_body->vertices();
	btVector3* out = m_skinMesh->beginPose();
	for (int i = 0; i < v.rows(); ++i)
		out[i].setValue(btScalar(v(i, 0)), btScalar(v(i, 1)), btScalar(v(i, 2)));
	m_skinMesh->endPose();
	const double seconds = btSecondsSince(t0);
	m_stats.meshSeconds += seconds;
	m_stats.lastMeshSeconds += seconds; // (writeMesh, which runs after, adds its own)
}

void btSkinnedBodyDriver::setFrameTolerance(double metres)
{
	if (!(metres >= 0.0) || !std::isfinite(metres))
		throw InvalidInputError("btSkinnedBodyDriver: the frame tolerance must be a finite length >= 0 (metres)");
	m_frameTolerance = metres;
}

void btSkinnedBodyDriver::writeBoneFrames()
{
	const std::vector<Eigen::Affine3d>& skinning = m_body->skinning();
	const int n = int(m_body->ellipsoids().size());
	m_frameBones.resize(n);
	m_bindToCurrent.resize(n, btTransform::getIdentity());
	for (int i = 0; i < n; ++i)
	{
		const int bone = m_body->dominantBone(i);
		m_frameBones[i] = -1;
		if (std::size_t(bone) >= skinning.size())
			continue;
		// Only a rigid skinning matrix carries distances: a scaled or sheared bone keeps the union response.
		const Eigen::Affine3d& s = skinning[std::size_t(bone)];
		const Eigen::Matrix3d r = s.linear();
		if (!((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-6) || !(r.determinant() > 0))
			continue;
		if (m_body->mode(i) != EllipsoidMotion::Rigid && !movesWithBone(i, bone, skinning))
			continue;
		m_frameBones[i] = bone;
		m_bindToCurrent[i] = btTransform(toBt(r), toBt(Eigen::Vector3d(s.translation())));
	}
	const char* why = 0;
	if (!m_compound->setBoneFrames(n, &m_frameBones[0], &m_bindToCurrent[0], &why))
		throw InvalidInputError(std::string("btSkinnedBodyDriver: ") + why);
}

bool btSkinnedBodyDriver::movesWithBone(int j, int bone, const std::vector<Eigen::Affine3d>& skinning) const
{
	// A skinned point v = sum_i w_i S_i v_bind (weights summing to 1) is within max_i |S_i v_bind - S_b v_bind| of
	// S_b v_bind, and over the ball (c, r) that holds the bind points (the bind ellipsoid's centre and largest
	// semi-axis) |S_i p - S_b p| <= |L_i - L_b|_F r + |S_i c - S_b c|.
	const Ellipsoid& e = m_body->bindEllipsoid(j);
	const double r = e.radii.maxCoeff();
	const Eigen::Affine3d& sb = skinning[std::size_t(bone)];
	for (int i : m_body->bones(j))
	{
		const Eigen::Affine3d& si = skinning[std::size_t(i)];
		if ((si.linear() - sb.linear()).norm() * r + (si * e.center - sb * e.center).norm() > m_frameTolerance)
			return false;
	}
	return true;
}

void btSkinnedBodyDriver::writeMesh()
{
	if (!m_mesh)
		return;
	const auto t0 = std::chrono::steady_clock::now();
	m_mesh->setVertices(m_body->vertices());
	const double seconds = btSecondsSince(t0);
	m_stats.lastMeshSeconds += seconds;
	m_stats.meshSeconds += seconds;
}

} // namespace bodyfit
