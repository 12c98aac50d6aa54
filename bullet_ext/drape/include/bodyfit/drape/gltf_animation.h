#pragma once
/// \file gltf_animation.h
/// A drape run as one glTF 2.0 binary file (.glb) that any glTF viewer plays: body and cloth at every written frame.
///
/// Layout. One node per frame holding one mesh with one primitive per part (body, cloth: positions and the part's
/// triangle indices, which every frame shares), and one animation whose channels set each frame node's scale with
/// STEP interpolation: 1 from its own frame time until the next frame's, 0 otherwise. Nodes other than the first
/// start at scale 0, so a viewer that does not play animations shows the first frame.
///
/// Why frame nodes and not morph targets: STEP scale keys are core glTF node animation, which every viewer that
/// plays animations supports; morph targets would interpolate linearly between frames (not show them in turn)
/// and many viewers cap the number of active targets (e.g. 4 or 8), far fewer than the frames of a run. The file
/// is as large either way (one position array per part and frame; indices stored once).

#include "bodyfit/fitting/types.h"

#include <string>
#include <vector>

namespace bodyfit::drape
{

/// One part drawn in every frame (the body, the cloth): name, colour (linear RGB, 0..1) and its triangles.
struct GltfPart
{
	std::string name;
	Eigen::Vector3f color{0.8f, 0.8f, 0.8f};
	bool doubleSided = false; ///< cloth: both sides lit
	Eigen::MatrixX3i faces;
};

/// Frames recorded over a run, written at the end (writeGlb).
class GltfAnimationRecorder
{
public:
	/// \throws InvalidInputError for no parts, a part without faces or with a negative index.
	explicit GltfAnimationRecorder(std::vector<GltfPart> parts);

	/// Adds a frame at `time` seconds: one vertex array per part, in the order of the parts.
	/// \throws InvalidInputError for a time not after the previous frame's, a wrong count of parts, non-finite
	/// coordinates, or a vertex count that a face index reaches beyond.
	void addFrame(double time, const std::vector<const Eigen::MatrixX3d*>& vertices);

	int frameCount() const { return int(times_.size()); }

	/// The whole file (glTF 2.0 binary: header, JSON chunk, BIN chunk). \throws InvalidInputError with no frame.
	std::string glb() const;
	/// Writes glb() to `path`. \throws InvalidInputError as glb(), MeshLoadError when the file cannot be written.
	void writeGlb(const std::string& path) const;

private:
	std::vector<GltfPart> parts_;
	std::vector<double> times_;
	std::vector<std::vector<std::vector<float>>> positions_; ///< [frame][part] x, y, z, x, ...
};

} // namespace bodyfit::drape
