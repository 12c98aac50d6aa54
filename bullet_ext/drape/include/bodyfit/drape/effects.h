#pragma once
/// \file effects.h
/// The scene effects that need work every substep: wind (steady + turbulent field through Bullet's aerodynamic
/// model), self collision (node-node repulsion), pins that follow the body, and body motion (keyframed kinematic
/// path). Effects that only configure Bullet once (gravity, aerodynamics without wind, friction, world pins) are
/// applied when the simulation is built and have no per-step code at all. An effect the scene does not list is
/// never constructed: no object, no call, no per-node branch.

#include "bodyfit/drape/scene.h"

#include <LinearMath/btTransform.h>

#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

class btSoftBody;
class btRigidBody;

namespace bodyfit::drape
{

/// Work counters, one set per simulation (tests use them to show that unlisted effects cost nothing).
struct EffectCounters
{
	long long windSubsteps = 0;       ///< substeps in which the wind field was evaluated
	long long windNodeForces = 0;     ///< aerodynamic force evaluations at nodes or faces
	long long selfCollisionSubsteps = 0;
	long long selfCollisionPairs = 0; ///< close node pairs examined
	long long selfCollisionImpulses = 0;
	long long pinSubsteps = 0;        ///< substeps in which body-attached pins were moved
	long long bodyMotionSubsteps = 0; ///< substeps in which the kinematic body pose was set
	long long animationSubsteps = 0;  ///< substeps in which an animated body was posed and its shape written
};

/// Keyframed rigid motion: p' = pivot + R(t) (p - pivot) + T(t), translation lerped and rotation slerped between
/// keys, clamped outside the key range (or wrapped, for looping motions).
class KeyframePath
{
public:
	KeyframePath(const BodyMotionSpec& spec, const Eigen::Vector3d& defaultPivot);
	btTransform at(double time) const;

private:
	BodyMotionSpec spec_;
	Eigen::Vector3d pivot_;
};

/// Smooth pseudo-random vector field n(x, t) in [-1, 1]^3 per component: 4D value noise (hashed lattice, quintic
/// fade) summed over octaves, each octave half the length/time scale and half the amplitude, normalised so the
/// sum stays in [-1, 1]. Deterministic for a given seed.
class TurbulenceField
{
public:
	TurbulenceField(double lengthScale, double timeScale, int octaves, unsigned seed);
	Eigen::Vector3d sample(const Eigen::Vector3d& x, double t) const;

private:
	double valueNoise(const double p[4], unsigned channelSeed) const;
	double invLength_, invTime_;
	int octaves_;
	unsigned seed_;
};

class Effect
{
public:
	virtual ~Effect() = default;
	virtual const char* name() const = 0;
	/// Called before each Bullet substep of length dt that starts at time t.
	virtual void beforeSubstep(double t, double dt) = 0;
};

/// Wind: per node (or per face for Bullet's F_* models) the local air velocity w = steady + turbulence * n(x, t)
/// is handed to btSoftBody::addAeroForceToNode / addAeroForceToFace, with the lift/drag coefficients of the
/// `aerodynamics` effect when it is listed and otherwise Bullet's V_TwoSided model with the wind's own drag.
class WindEffect : public Effect
{
public:
	WindEffect(const WindSpec& wind, const std::optional<AerodynamicsSpec>& aero, btSoftBody* cloth,
			   EffectCounters& counters);
	const char* name() const override { return "wind"; }
	void beforeSubstep(double t, double dt) override;
	/// Air velocity at a point (for tests and pictures).
	Eigen::Vector3d airVelocity(const Eigen::Vector3d& x, double t) const;

private:
	WindSpec wind_;
	TurbulenceField field_;
	btSoftBody* cloth_;
	int model_;
	double lift_, drag_;
	EffectCounters& counters_;
};

/// Self collision: Bullet's classic soft world has no vertex-face self collision for cloth (VF_SS skips
/// psb == this; CL_SELF needs clusters). Before each substep, every pair of nodes that are not linked and were
/// not already that close at rest, whose predicted distance along their current separation drops below
/// `thickness`, gets equal and opposite velocity impulses (mass-weighted) removing `stiffness` of the shortfall.
/// Pairs come from a uniform hash grid rebuilt each substep (O(nodes)). Running before the solve keeps the
/// body collider's guarantee intact (the collider acts last).
class SelfCollisionEffect : public Effect
{
public:
	SelfCollisionEffect(const SelfCollisionSpec& spec, btSoftBody* cloth, EffectCounters& counters);
	const char* name() const override { return "self_collision"; }
	void beforeSubstep(double t, double dt) override;

private:
	/// The distance within which pairs are tested this substep.
	double searchRadius(double dt) const;
	/// keys_ (per node its cell key, sorted) and cells_ (per occupied cell its range of keys_), cells of edge 1 / inv.
	void binNodes(double inv);
	/// Nodes i and j closer than radius, not that close at rest nor linked, that would come within the thickness in
	/// this substep: the relative normal speed that keeps them at the thickness, times the stiffness, shared by
	/// inverse mass.
	void repel(int i, int j, double radius, double dt);

	SelfCollisionSpec spec_;
	btSoftBody* cloth_;
	EffectCounters& counters_;
	std::vector<Eigen::Vector3d> rest_;
	std::vector<std::vector<int>> linked_; ///< sorted neighbour lists (structural and bending links)
	std::vector<std::pair<std::uint64_t, int>> keys_;
	std::unordered_map<std::uint64_t, std::pair<int, int>> cells_;
};

/// The kinematic body follows a KeyframePath (its motion state is set to the pose at the end of each substep,
/// Bullet derives the body velocity from it in saveKinematicState).
class BodyMotionEffect : public Effect
{
public:
	BodyMotionEffect(const KeyframePath& path, btRigidBody* body, EffectCounters& counters);
	const char* name() const override { return "body_motion"; }
	void beforeSubstep(double t, double dt) override;

private:
	KeyframePath path_;
	btRigidBody* body_;
	EffectCounters& counters_;
};

/// Pinned nodes (inverse mass 0) carried by the moving body: before each substep a node's velocity is set so
/// that Bullet's integration (x += v dt) lands it on its body-attached position at the end of the substep.
class BodyPinEffect : public Effect
{
public:
	BodyPinEffect(const std::vector<int>& nodes, const KeyframePath& path, btSoftBody* cloth,
				  EffectCounters& counters);
	const char* name() const override { return "pin"; }
	void beforeSubstep(double t, double dt) override;

private:
	std::vector<int> nodes_;
	std::vector<btVector3> local_; ///< node positions in the body frame at t = 0
	KeyframePath path_;
	btSoftBody* cloth_;
	EffectCounters& counters_;
};

/// Bullet's aerodynamic model id for a scene name ("V_TwoSidedLiftDrag" -> btSoftBody::eAeroModel::...).
int aeroModelFromName(const std::string& name);

} // namespace bodyfit::drape
