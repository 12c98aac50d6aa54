/*
bodyfit: bridge from the fitter's output (bodyfit::Ellipsoid, double) to Bullet (btEllipsoidCompoundShape).
This is the edge between the two dialects: it throws bodyfit exceptions (errors.h), Bullet code never does.
*/

#ifndef BT_BODYFIT_TO_BULLET_H
#define BT_BODYFIT_TO_BULLET_H

#include <memory>
#include <string>
#include <vector>

#include "bodyfit/fitting/ellipsoid.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"

namespace bodyfit
{

struct CompoundOptions
{
	double childMargin = double(BT_ELLIPSOID_DEFAULT_MARGIN); ///< collision margin of each btEllipsoidShape (metres)
};

/// One child per ellipsoid, same order (child i = ellipsoids[i]).
/// \throws InvalidInputError naming the first ellipsoid that is not valid (Ellipsoid::isValid) or if the list is empty.
std::unique_ptr<btEllipsoidCompoundShape> createEllipsoidCompound(const std::vector<Ellipsoid>& ellipsoids,
																  const CompoundOptions& options = {});

/// Reads an ellipsoid JSON file (the format written by bodyfit-fit, see ellipsoid_io.h) and builds the compound.
/// \throws MeshLoadError / FormatError from the reader, InvalidInputError as above.
std::unique_ptr<btEllipsoidCompoundShape> loadEllipsoidCompound(const std::string& jsonPath,
																const CompoundOptions& options = {});

/// The compound's ellipsoids back in the fitter's types (compound-local frame, local scaling applied).
std::vector<Ellipsoid> toEllipsoids(const btEllipsoidCompoundShape& compound);

} // namespace bodyfit

#endif // BT_BODYFIT_TO_BULLET_H
