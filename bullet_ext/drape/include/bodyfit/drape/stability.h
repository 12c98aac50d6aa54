#pragma once
/// \file stability.h
/// Detects a drape run that blew up (docs/ROBUSTNESS.md 7.9-7.10): a cloth node with a non-finite position or
/// velocity, or one farther from where the run started than any physical motion of the scene can take it. The
/// scene ranges of scene.h keep accepted scenes stable; this is the check that a run which still blows up does not
/// end with exit 0 and plausible-looking metrics (a node thrown 1e6 m away is outside every ellipsoid).

#include <Eigen/Geometry>

#include <string>

namespace bodyfit::drape
{

class DrapeSimulation;

/// Created before the first step (it records the start), then asked after each step.
class BlowUpWatch
{
public:
	explicit BlowUpWatch(const DrapeSimulation& sim);

	/// "" while every node is finite and within reach(t) of the start box, else a one-line reason naming the node.
	std::string check(const DrapeSimulation& sim) const;

	/// Bound on the distance (m) a node can be from the start box after `seconds`:
	/// 1 m + v t + |g| t^2, with v = 10 m/s + 3 (|wind| + sqrt(3) turbulence) + 2 (the body's fastest keyframed
	/// speed, rotation included at the radius of the start box) and |g| t^2 twice free fall. Drag only slows cloth
	/// down and links only hold it together, so a physical run stays well inside it.
	double reach(double seconds) const;

	const Eigen::AlignedBox3d& startBox() const { return start_; }

private:
	Eigen::AlignedBox3d start_;
	double speed_ = 0.0;   ///< v of reach(), m/s
	double gravity_ = 0.0; ///< |g|, m/s^2
};

} // namespace bodyfit::drape
