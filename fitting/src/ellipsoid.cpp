// Ellipsoid geometry: zeta, radial projection, normals, AABB, segment entry and Eberly's closest point.
// Every query works in the ellipsoid's local frame (relative to its centre), so results do not degrade when the
// ellipsoid sits far from the world origin.
#include "bodyfit/fitting/ellipsoid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace bodyfit
{

namespace
{

constexpr double kPi = 3.14159265358979323846;

/// Index of the longest semi-axis (the first one on ties, so results are deterministic).
int longestAxis(const Eigen::Vector3d& radii)
{
	int best = 0;
	for (int i = 1; i < 3; ++i)
		if (radii[i] > radii[best])
			best = i;
	return best;
}

/// Point of the unit sphere (in the scaled local frame s = diag(1/r) R^T (p - c)) on the ray from the origin
/// through s, computed without overflow or underflow. Returns false when s is zero or not finite.
bool unitDirection(const Eigen::Vector3d& s, Eigen::Vector3d& unit)
{
	const double m = s.cwiseAbs().maxCoeff();
	if (!(m > 0.0) || !std::isfinite(m))
		return false;
	const Eigen::Vector3d scaled = s / m; // largest component is +-1: its norm neither overflows nor underflows
	unit = scaled / scaled.norm();
	return true;
}

// ---- Eberly, "Distance from a Point to an Ellipse, an Ellipsoid, or a Hyperellipsoid" (robust bisection) ------
// Inputs are sorted extents e0 >= e1 (>= e2) and a query in the first octant (y_i >= 0).

/// Largest iteration count a bisection on doubles can need (the bracket halves until its ends are adjacent).
constexpr int kMaxBisections = 1200;

double robustLength(double a, double b)
{
	const double m = std::max(std::abs(a), std::abs(b));
	if (m == 0.0)
		return 0.0;
	return m * std::sqrt((a / m) * (a / m) + (b / m) * (b / m));
}

double robustLength(double a, double b, double c)
{
	const double m = std::max({std::abs(a), std::abs(b), std::abs(c)});
	if (m == 0.0)
		return 0.0;
	return m * std::sqrt((a / m) * (a / m) + (b / m) * (b / m) + (c / m) * (c / m));
}

// Eberly bisects on s with poles at s = -r_i (r_i = (e_i/e_last)^2). We bisect on t = s + 1 instead, with the
// offsets d_i = r_i - 1 formed from the extents directly: a query a hair off the plane of the smallest axis (y_last ~
// 1e-17 from rounding) puts the root at t ~ 1e-16, which s = t - 1 cannot resolve but t can.

/// Root t > 0 of F(t) = (n0/(t + d0))^2 + (z1/t)^2 - 1, by bisection.
double ellipseRoot(double n0, double d0, double z1, double g)
{
	double t0 = z1;
	double t1 = g < 0.0 ? 1.0 : robustLength(n0, z1);
	double t = t0;
	for (int i = 0; i < kMaxBisections; ++i)
	{
		t = 0.5 * (t0 + t1);
		if (t == t0 || t == t1)
			break;
		const double a = n0 / (t + d0), b = z1 / t;
		const double f = a * a + b * b - 1.0;
		if (f > 0.0)
			t0 = t;
		else if (f < 0.0)
			t1 = t;
		else
			break;
	}
	return t;
}

/// Root t > 0 of F(t) = (n0/(t + d0))^2 + (n1/(t + d1))^2 + (z2/t)^2 - 1, by bisection.
double ellipsoidRoot(double n0, double d0, double n1, double d1, double z2, double g)
{
	double t0 = z2;
	double t1 = g < 0.0 ? 1.0 : robustLength(n0, n1, z2);
	double t = t0;
	for (int i = 0; i < kMaxBisections; ++i)
	{
		t = 0.5 * (t0 + t1);
		if (t == t0 || t == t1)
			break;
		const double a = n0 / (t + d0), b = n1 / (t + d1), c = z2 / t;
		const double f = a * a + b * b + c * c - 1.0;
		if (f > 0.0)
			t0 = t;
		else if (f < 0.0)
			t1 = t;
		else
			break;
	}
	return t;
}

/// Closest point of the ellipse (x0/e0)^2 + (x1/e1)^2 = 1 to (y0, y1), e0 >= e1 > 0, y >= 0.
void closestOnEllipse(double e0, double e1, double y0, double y1, double& x0, double& x1)
{
	if (y1 > 0.0)
	{
		if (y0 > 0.0)
		{
			const double z0 = y0 / e0, z1 = y1 / e1;
			const double g = z0 * z0 + z1 * z1 - 1.0;
			if (g != 0.0)
			{
				const double r0 = (e0 / e1) * (e0 / e1), d0 = (e0 - e1) * (e0 + e1) / (e1 * e1);
				const double t = ellipseRoot(r0 * z0, d0, z1, g);
				x0 = r0 * y0 / (t + d0);
				x1 = y1 / t;
			}
			else
			{
				x0 = y0;
				x1 = y1;
			}
		}
		else
		{
			x0 = 0.0;
			x1 = e1;
		}
		return;
	}
	// y1 == 0: the answer leaves the axis only when y0 lies inside the evolute's cusp.
	const double numer0 = e0 * y0, denom0 = e0 * e0 - e1 * e1;
	if (numer0 < denom0)
	{
		const double xde0 = numer0 / denom0;
		x0 = e0 * xde0;
		x1 = e1 * std::sqrt(std::max(0.0, 1.0 - xde0 * xde0));
	}
	else
	{
		x0 = e0;
		x1 = 0.0;
	}
}

/// Closest point of the ellipsoid with sorted extents e0 >= e1 >= e2 > 0 to y (first octant).
Eigen::Vector3d closestOnSortedEllipsoid(const Eigen::Vector3d& e, const Eigen::Vector3d& y)
{
	Eigen::Vector3d x;
	if (y[2] > 0.0)
	{
		if (y[1] > 0.0)
		{
			if (y[0] > 0.0)
			{
				const Eigen::Vector3d z = y.cwiseQuotient(e);
				const double g = z.squaredNorm() - 1.0;
				if (g != 0.0)
				{
					const double r0 = (e[0] / e[2]) * (e[0] / e[2]), r1 = (e[1] / e[2]) * (e[1] / e[2]);
					const double d0 = (e[0] - e[2]) * (e[0] + e[2]) / (e[2] * e[2]);
					const double d1 = (e[1] - e[2]) * (e[1] + e[2]) / (e[2] * e[2]);
					const double t = ellipsoidRoot(r0 * z[0], d0, r1 * z[1], d1, z[2], g);
					x << r0 * y[0] / (t + d0), r1 * y[1] / (t + d1), y[2] / t;
				}
				else
				{
					x = y;
				}
			}
			else
			{
				x[0] = 0.0;
				closestOnEllipse(e[1], e[2], y[1], y[2], x[1], x[2]);
			}
		}
		else
		{
			x[1] = 0.0;
			if (y[0] > 0.0)
				closestOnEllipse(e[0], e[2], y[0], y[2], x[0], x[2]);
			else
			{
				x[0] = 0.0;
				x[2] = e[2];
			}
		}
		return x;
	}
	// y2 == 0: the closest point leaves the plane x2 = 0 only when y is inside the evolute's region there.
	const double denom0 = e[0] * e[0] - e[2] * e[2], denom1 = e[1] * e[1] - e[2] * e[2];
	const double numer0 = e[0] * y[0], numer1 = e[1] * y[1];
	if (numer0 < denom0 && numer1 < denom1)
	{
		const double xde0 = numer0 / denom0, xde1 = numer1 / denom1;
		const double discr = 1.0 - xde0 * xde0 - xde1 * xde1;
		if (discr > 0.0)
		{
			x << e[0] * xde0, e[1] * xde1, e[2] * std::sqrt(discr);
			return x;
		}
	}
	x[2] = 0.0;
	closestOnEllipse(e[0], e[1], y[0], y[1], x[0], x[1]);
	return x;
}

} // namespace

double Ellipsoid::zeta(const Eigen::Vector3d& p) const
{
	return toLocal(p).cwiseQuotient(radii).squaredNorm();
}

Eigen::Vector3d Ellipsoid::radialProjection(const Eigen::Vector3d& p) const
{
	const Eigen::Vector3d s = toLocal(p).cwiseQuotient(radii);
	Eigen::Vector3d unit;
	if (!unitDirection(s, unit))
	{
		const int a = longestAxis(radii);
		return center + rotation.col(a) * radii[a];
	}
	return toWorld(unit.cwiseProduct(radii));
}

Eigen::Vector3d Ellipsoid::normalAt(const Eigen::Vector3d& p) const
{
	// The level set of zeta through p is the ellipsoid scaled about the centre, so its normal equals the surface
	// normal at the radial projection: gradient direction diag(1/r) * unit, with unit on the unit sphere.
	const Eigen::Vector3d s = toLocal(p).cwiseQuotient(radii);
	Eigen::Vector3d unit;
	if (!unitDirection(s, unit))
		return rotation.col(longestAxis(radii));
	Eigen::Vector3d g = unit.cwiseQuotient(radii);
	g /= g.cwiseAbs().maxCoeff(); // finite radii > 0 keep this finite and non-zero
	return rotation * g.normalized();
}

double Ellipsoid::volume() const
{
	return 4.0 / 3.0 * kPi * radii[0] * radii[1] * radii[2];
}

Eigen::AlignedBox3d Ellipsoid::aabb() const
{
	// Support of the ellipsoid along world axis i: sqrt(sum_j (R_ij r_j)^2).
	const Eigen::Matrix3d scaledAxes = rotation * radii.asDiagonal();
	const Eigen::Vector3d half = scaledAxes.rowwise().norm();
	return Eigen::AlignedBox3d(center - half, center + half);
}

bool Ellipsoid::isValid(double tolerance) const
{
	if (!center.allFinite() || !rotation.allFinite() || !radii.allFinite())
		return false;
	if ((radii.array() <= 0.0).any())
		return false;
	if ((rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > tolerance)
		return false;
	return std::abs(rotation.determinant() - 1.0) <= tolerance;
}

SegmentEntry segmentEntry(const Ellipsoid& e, const Eigen::Vector3d& q, const Eigen::Vector3d& x)
{
	SegmentEntry result;
	// Unit-sphere frame: a = start, d = direction (x - q mapped with the linear part only, so q == x gives d = 0).
	const Eigen::Vector3d a = e.toLocal(q).cwiseQuotient(e.radii);
	const Eigen::Vector3d d = (e.rotation.transpose() * (x - q)).cwiseQuotient(e.radii);
	const double c = a.squaredNorm() - 1.0;
	if (c <= 0.0)
	{
		result.hit = true;
		result.startsInside = true;
		result.t = 0.0;
		return result;
	}
	const double dd = d.squaredNorm();
	const double b = a.dot(d); // half of the linear coefficient
	if (!(dd > 0.0) || !(b < 0.0))
		return result; // degenerate segment outside, or moving away from / tangent to the centre: no entry
	const bool endsInside = e.toLocal(x).cwiseQuotient(e.radii).squaredNorm() <= 1.0;

	// Stable discriminant (Ray Tracing Gems ch. 7): b^2 - dd*c = dd * (1 - |a_perp|^2) with a_perp the part of a
	// orthogonal to d; (1 - l)(1 + l) avoids cancelling two nearly equal squares.
	const Eigen::Vector3d aPerp = a - (b / dd) * d;
	const double l = aPerp.norm();
	double disc = dd * (1.0 - l) * (1.0 + l);
	if (disc < 0.0)
	{
		if (!endsInside)
			return result; // the line misses the sphere
		disc = 0.0;        // rounding: the end point is inside, so the line must cross
	}
	// Near root t0 = c / (-b + sqrt(disc)): -b > 0, so the denominator adds two non-negative numbers.
	double t = c / (-b + std::sqrt(disc));
	if (!(t <= 1.0))
	{
		if (!endsInside)
			return result;
		t = 1.0;
	}
	result.hit = true;
	result.t = std::max(0.0, t);
	return result;
}

SurfacePoint closestSurfacePoint(const Ellipsoid& e, const Eigen::Vector3d& p)
{
	const Eigen::Vector3d local = e.toLocal(p);
	// Sort the axes by decreasing extent (stable, so ties keep their order) and reflect into the first octant.
	std::array<int, 3> order = {0, 1, 2};
	std::stable_sort(order.begin(), order.end(), [&](int i, int j) { return e.radii[i] > e.radii[j]; });
	Eigen::Vector3d extents, y;
	for (int k = 0; k < 3; ++k)
	{
		extents[k] = e.radii[order[k]];
		y[k] = std::abs(local[order[k]]);
	}
	const Eigen::Vector3d x = closestOnSortedEllipsoid(extents, y);

	Eigen::Vector3d closestLocal;
	for (int k = 0; k < 3; ++k)
		closestLocal[order[k]] = std::copysign(x[k], local[order[k]]);
	SurfacePoint result;
	result.point = e.toWorld(closestLocal);
	const double distance = (x - y).norm(); // in the local frame: no cancellation against far-away coordinates
	const bool inside = y.cwiseQuotient(extents).squaredNorm() < 1.0;
	result.signedDistance = inside ? -distance : distance;
	return result;
}

Eigen::Quaterniond toQuaternion(const Eigen::Matrix3d& rotation)
{
	Eigen::Quaterniond q(rotation);
	q.normalize();
	if (q.w() < 0.0)
		q.coeffs() = -q.coeffs(); // canonical sign: w >= 0, so equal rotations give equal files
	return q;
}

} // namespace bodyfit
