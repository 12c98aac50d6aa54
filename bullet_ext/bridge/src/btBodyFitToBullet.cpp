/*
bodyfit: bridge from bodyfit::Ellipsoid to btEllipsoidCompoundShape. See btBodyFitToBullet.h.
*/

#include "bodyfit/bridge/btBodyFitToBullet.h"

#include "bodyfit/fitting/ellipsoid_io.h"
#include "bodyfit/fitting/errors.h"

#include "bodyfit/bridge/btEigenConversion.h"

#include <cstdint>
#include <sstream>
#include <string>

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

std::unique_ptr<btSkinDistanceField> createSkinDistanceField(const SkinField& field)
{
	static_assert(sizeof(int) == sizeof(std::int32_t) && sizeof(short) == sizeof(std::int16_t),
				  "btSkinDistanceField::set takes the layout's int32 index and int16 samples as int and short");
	btSkinFieldLayout layout;
	for (int k = 0; k < 3; ++k)
		layout.m_origin[k] = field.origin[k];
	layout.m_voxelSize = field.voxel;
	layout.m_brickEdge = kSkinBrickEdge;
	layout.m_bricks[0] = field.nx, layout.m_bricks[1] = field.ny, layout.m_bricks[2] = field.nz;
	layout.m_clamp = field.clamp;
	layout.m_maxError = field.maxError;
	layout.m_skinOffset = field.skinOffset;
	std::unique_ptr<btSkinDistanceField> out(new btSkinDistanceField());
	const char* error = nullptr;
	if (!out->set(layout, reinterpret_cast<const int*>(field.brickIndex.data()), (long long)field.brickIndex.size(),
				  reinterpret_cast<const short*>(field.samples.data()), (long long)field.samples.size(), &error))
		throw InvalidInputError(std::string("skin field: ") + (error ? error : "refused by btSkinDistanceField::set"));
	return out;
}

namespace
{

/// The compound takes the fit's field (converted) as its own. \throws InvalidInputError "skin field: ...".
void attachSkinField(btEllipsoidCompoundShape& compound, const SkinField& skin)
{
	std::unique_ptr<btSkinDistanceField> field = createSkinDistanceField(skin);
	const char* error = nullptr;
	if (!compound.setSkinField(field.get(), /*owned=*/true, &error))
		throw InvalidInputError(std::string("skin field: not attached: ") + (error ? error : "refused"));
	field.release(); // the compound owns it now
}

std::vector<Ellipsoid> ellipsoidsOf(const BodyFit& fit)
{
	std::vector<Ellipsoid> out;
	out.reserve(fit.ellipsoids.size());
	for (const FittedEllipsoid& f : fit.ellipsoids)
		out.push_back(f.ellipsoid);
	return out;
}

} // namespace

std::unique_ptr<btEllipsoidCompoundShape> createBodyFitCompound(const BodyFit& fit, const CompoundOptions& options)
{
	std::unique_ptr<btEllipsoidCompoundShape> compound = createEllipsoidCompound(ellipsoidsOf(fit), options);
	if (fit.skinField && options.attachSkinField)
		attachSkinField(*compound, *fit.skinField);
	return compound;
}

std::unique_ptr<btEllipsoidCompoundShape> loadEllipsoidCompound(const std::string& jsonPath,
																const CompoundOptions& options)
{
	const BodyFit fit = readEllipsoidJson(jsonPath);
	if (fit.ellipsoids.empty())
		throw InvalidInputError(jsonPath + ": ellipsoids: the file lists no ellipsoids");
	std::unique_ptr<btEllipsoidCompoundShape> compound = createEllipsoidCompound(ellipsoidsOf(fit), options);
	if (fit.skinField && options.attachSkinField)
	{
		try
		{
			attachSkinField(*compound, *fit.skinField);
		}
		catch (const InvalidInputError& e)
		{
			throw InvalidInputError(jsonPath + ": " + e.what());
		}
	}
	return compound;
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
