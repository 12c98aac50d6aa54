/*
bodyfit: bridge from bodyfit::Ellipsoid to btEllipsoidCompoundShape. See btBodyFitToBullet.h.
*/

#include "bodyfit/bridge/btBodyFitToBullet.h"

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"

#include "bodyfit/bridge/btEigenConversion.h"

#include <sstream>

namespace bodyfit
{

std::unique_ptr<btEllipsoidCompoundShape> createEllipsoidCompound(const std::vector<Ellipsoid>& ellipsoids,
																  const CompoundOptions& options)
{
	if (ellipsoids.empty())
		throw InvalidInputError("createEllipsoidCompound: the ellipsoid list is empty");
	if (!(options.childMargin >= 0.0) || !std::isfinite(options.childMargin))
		throw InvalidInputError("createEllipsoidCompound: childMargin must be finite and >= 0");
	for (size_t i = 0; i < ellipsoids.size(); ++i)
		if (!ellipsoids[i].isValid())
		{
			std::ostringstream msg;
			msg << "createEllipsoidCompound: ellipsoid " << i
				<< " is not valid (non-finite values, radii <= 0 or rotation not a proper rotation)";
			throw InvalidInputError(msg.str());
		}
	std::unique_ptr<btEllipsoidCompoundShape> compound(new btEllipsoidCompoundShape(btScalar(options.childMargin)));
	for (const Ellipsoid& e : ellipsoids)
		compound->addEllipsoid(toBt(e.center), toBt(e.rotation), toBt(e.radii));
	return compound;
}

std::unique_ptr<btEllipsoidCompoundShape> loadEllipsoidCompound(const std::string& jsonPath,
																const CompoundOptions& options)
{
	const BodyFit fit = readEllipsoidJson(jsonPath);
	std::vector<Ellipsoid> ellipsoids;
	ellipsoids.reserve(fit.ellipsoids.size());
	for (const FittedEllipsoid& f : fit.ellipsoids)
		ellipsoids.push_back(f.ellipsoid);
	if (ellipsoids.empty())
		throw InvalidInputError(jsonPath + ": ellipsoids: the file lists no ellipsoids");
	return createEllipsoidCompound(ellipsoids, options);
}

std::vector<Ellipsoid> toEllipsoids(const btEllipsoidCompoundShape& compound)
{
	std::vector<Ellipsoid> out;
	out.reserve(size_t(compound.getNumEllipsoids()));
	for (int i = 0; i < compound.getNumEllipsoids(); ++i)
	{
		const btEllipsoidLocalData& d = compound.getEllipsoid(i);
		Ellipsoid e;
		e.center = toEigen(d.m_center);
		e.rotation = toEigen(d.m_basis);
		e.radii = toEigen(d.m_semiAxes);
		out.push_back(e);
	}
	return out;
}

} // namespace bodyfit
