/*
bodyfit: bridge from the fitter's output (bodyfit::Ellipsoid, double) to Bullet (btEllipsoidCompoundShape).
This is the edge between the two dialects: it throws bodyfit exceptions (errors.h), Bullet code never does.
*/

#ifndef BT_BODYFIT_TO_BULLET_H
#define BT_BODYFIT_TO_BULLET_H

#include <memory>
#include <string>
#include <vector>

#include "bodyfit/fitting/body_fitter.h"
#include "bodyfit/fitting/ellipsoid.h"
#include "bodyfit/fitting/skin_field.h"

#include "bodyfit/bullet_ext/btEllipsoidCompoundShape.h"
#include "bodyfit/bullet_ext/btSkinDistanceField.h"

namespace bodyfit
{

struct CompoundOptions
{
	double childMargin = double(BT_ELLIPSOID_DEFAULT_MARGIN); ///< collision margin of each btEllipsoidShape (metres)
	/// A fit with a skin field (skin_field.h) gets it attached to its compound (btEllipsoidCompoundShape::setSkinField,
	/// owned by the compound), for the collider's tight mode.
	bool attachSkinField = true;
};

/// One child per ellipsoid, same order (child i = ellipsoids[i]).
/// \throws InvalidInputError naming the first ellipsoid that is not valid (Ellipsoid::isValid) or if the list is empty.
std::unique_ptr<btEllipsoidCompoundShape> createEllipsoidCompound(const std::vector<Ellipsoid>& ellipsoids,
																  const CompoundOptions& options = {});

/// The fitter's skin field as the Bullet-side field: the same layout (origin, voxel, clamp, max error, skin offset,
/// brick index, samples), copied and validated by btSkinDistanceField::set.
/// \throws InvalidInputError "skin field: <set's reason>" when set refuses it.
std::unique_ptr<btSkinDistanceField> createSkinDistanceField(const SkinField& field);

/// The compound of a fit: one child per ellipsoid (createEllipsoidCompound above) and, when the fit has a skin field
/// and options.attachSkinField, that field attached (owned by the compound).
/// \throws InvalidInputError as createEllipsoidCompound and createSkinDistanceField.
std::unique_ptr<btEllipsoidCompoundShape> createBodyFitCompound(const BodyFit& fit, const CompoundOptions& options = {});

/// Reads an ellipsoid JSON file (the format written by bodyfit-fit, see ellipsoid_io.h) and builds the compound, with
/// the fit's skin field attached when the file names one (its side file is read with it) and options.attachSkinField.
/// \throws MeshLoadError / FormatError from the reader, InvalidInputError as above.
std::unique_ptr<btEllipsoidCompoundShape> loadEllipsoidCompound(const std::string& jsonPath,
																const CompoundOptions& options = {});

/// The compound's ellipsoids back in the fitter's types (compound-local frame, local scaling applied).
std::vector<Ellipsoid> toEllipsoids(const btEllipsoidCompoundShape& compound);

} // namespace bodyfit

#endif // BT_BODYFIT_TO_BULLET_H
