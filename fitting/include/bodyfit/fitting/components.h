#pragma once
/// \file components.h
/// Bodies made of several meshes (game assets): which connected components form the body, which lie inside it and
/// which are detached props, and the virtual "bridge" edges that join the body's components so that geodesics (and
/// therefore the segmentation) see one body.
///
/// Classification (component 0 = the one with the most vertices, see connectedComponents in mesh_io.h):
///  - Inside: every sampled vertex of the component lies inside a larger component (ray-parity vote of
///    MeshInsideTest): eyes, teeth, a tongue inside the head.
///  - Attached: the component comes closer than `gap` to the surface of another component of the body, or some
///    of its vertices lie inside one (it passes through it): a head, hands or arms modelled as separate meshes that
///    touch the body or float a few mm from it. Joined transitively (a hand near an arm that is near the torso).
///  - Detached: everything else (props far from the body); also inner parts of a detached component.
/// gap = relativeGap x the largest extent of component 0's bounding box.
/// Deterministic: no randomness, ordered containers only; the answer does not depend on the vertex order within a
/// component except through which vertices are sampled for the inside test.

#include "bodyfit/fitting/types.h"

#include <string>
#include <utility>
#include <vector>

namespace bodyfit
{

enum class ComponentRole
{
	Body,     ///< component 0
	Attached, ///< joined to the body (touching, a few mm away, or passing through it)
	Inside,   ///< enclosed by a component of the body
	Detached, ///< neither: not part of the body
};
const char* toString(ComponentRole role);

struct ComponentOptions
{
	/// Components closer than this fraction of the body's largest bounding-box extent are one body: 0.01 = 17 mm on
	/// a 1.7 m figure, far more than the few mm between the parts of a game asset and less than the gap between a
	/// hanging hand and the thigh (which must stay apart for the geodesics).
	double relativeGap = 0.01;
	/// Vertices tested per component for "inside another component" (evenly spread over its vertex list).
	int insideSamples = 32;
};

struct MeshComponent
{
	int vertices = 0;
	ComponentRole role = ComponentRole::Body;
	int host = -1; ///< Inside: the component that encloses it; Attached: the component it was joined to first
};

struct ComponentLayout
{
	std::vector<int> vertexComponent;        ///< per vertex (0 = most vertices)
	std::vector<MeshComponent> components;
	std::vector<std::pair<int, int>> bridges; ///< vertex pairs (a < b) joining different Body/Attached components
	double gap = 0.0;                         ///< metres (the mesh's unit)

	/// True for vertices of Body and Attached components (what geodesics and the segmentation work on).
	bool onBody(int vertex) const;
	/// True for every vertex except those of Detached components (what is fitted).
	bool kept(int vertex) const;
	int count(ComponentRole role) const;
	int vertexCount(ComponentRole role) const;
};

/// Classifies the connected components of `mesh` (see above) and finds the bridges between the body's components.
ComponentLayout analyzeComponents(const TriMesh& mesh, const ComponentOptions& options = {});

/// Per vertex: the nearest (Euclidean) vertex with onBody() true, or the vertex itself when it is on the body.
std::vector<int> nearestBodyVertex(const TriMesh& mesh, const ComponentLayout& layout);

/// One-line warnings describing what the layout joined, found inside, or left out (empty for a single component).
std::vector<std::string> componentWarnings(const ComponentLayout& layout);

} // namespace bodyfit
