#pragma once
// The blood on the organ's surface, as the views draw it (simcore, no Qt; the loss itself is OperativeField's). Blood
// from an open stump runs down the surface as a film and leaves the organ where the surface turns under (or at its
// lowest point): the surface holds what flowed out over the time the film takes to run off, not everything lost (a
// minute of an 11 mL/s bleed is 0.7 L: as a 0.5 mm film that is 1.4 m^2, and the whole organ was drawn in blood; issue
// 61). The film runs at the mean speed of a falling film of its thickness on each edge's slope (Nusselt; Bird, Stewart
// and Lightfoot, Transport Phenomena, 2nd ed., section 2.2: u = rho g h^2 sin(theta) / (3 mu)); it covers the nodes it
// reaches first, so a bleed draws a stream down from the stump that widens as the rate grows (a stream of rate Q at
// speed u and thickness h is Q / (u h) wide) and pools where the surface holds it.
#include <rehearse/simcore/session/field.hpp>

#include <Eigen/Core>

#include <array>
#include <vector>

namespace rehearse::simcore {

struct BloodFilmSettings {
  double thickness = 0.0005;  ///< m: the film's thickness
  double density = 1060;      ///< kg/m^3 (whole blood)
  double viscosity = 0.0035;  ///< Pa s (whole blood at high shear rates, 3-4 mPa s)
  double gravity = 9.81;      ///< m/s^2
  /// The least share of the film's speed down a vertical wall it has on any edge: across a slope, or up a small rise
  /// of the mesh, blood still spreads (pushed by the blood behind it), slowly.
  double crawl = 0.1;
  /// A node where the surface faces down at least this much (its normal's cosine with gravity) drips: blood leaves
  /// the organ there. Blood also leaves at the organ's lowest nodes (within `lowest`, m, of the lowest).
  double drips = 0.7;
  double lowest = 0.001;
  /// s: blood stays on the surface at least this long, where it leaves the organ at once too (it wets the cut).
  double wets = 0.25;
};

/// m/s: the mean speed of a falling film of `thickness` (m) on a slope whose sine is `sine` (Nusselt's film).
double filmSpeed(double thickness, double sine, const BloodFilmSettings& s = {});

/// Each surface node's neighbours along the triangles' edges (nodes 0..n-1; others left out).
std::vector<std::vector<int>> surfaceNeighbours(const std::vector<std::array<int, 3>>& triangles, std::size_t n);

struct BloodFilm {
  std::vector<double> film;      ///< per node 0..1: 0 dry, 1 at a stump, thinner where the blood has just arrived
  std::vector<double> onSurface;  ///< per bleed, m^3: the blood on the surface (min(lost, rate * max(runOff, wets)))
  std::vector<double> runOff;     ///< per bleed, s: the time the film takes from the stump to where it leaves the organ
                                  ///< (infinite where it cannot leave: it pools)
  std::vector<double> covered;    ///< per bleed, m^2: the area of the nodes its film covers
  std::vector<int> source;        ///< per bleed: the node its stream starts from (the stump's, or its incision's spill)
};

/// The film of `bleeds` on the surface `triangles` at node positions `live`, `neighbours` from surfaceNeighbours,
/// `down` gravity's direction (unit; zero: no gravity, the film spreads evenly and never runs off). A stump's blood
/// covers the nodes it reaches soonest (each node's area a third of its triangles') until their area holds its blood
/// on the surface at the film's thickness. Deterministic.
/// `cutFaces` (per triangle, nonzero for a cut's face; empty: none): a stump inside an incision is driven out by the
/// vessel's pressure at the incision's mouth nearest it (along the incision's faces), not its lowest lip: the incision
/// is drawn full as far around the stump as that mouth, and the stream starts there. (A cut trunk deep in an incision
/// first ran down its walls and off the organ's back; then, filling to the lowest lip, out at the organ's side under a
/// laparoscope looking down: either way the camera saw no blood.)
BloodFilm bloodFilm(const std::vector<Bleed>& bleeds, const std::vector<Eigen::Vector3d>& live,
                    const std::vector<std::array<int, 3>>& triangles, const std::vector<std::vector<int>>& neighbours,
                    const Eigen::Vector3d& down, const BloodFilmSettings& s = {},
                    const std::vector<char>& cutFaces = {});

}  // namespace rehearse::simcore
