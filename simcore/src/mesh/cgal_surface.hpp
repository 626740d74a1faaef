#pragma once
// Private: conversion of a Mesh part to a CGAL Surface_mesh (only included by the CGAL translation units).
#include <rehearse/simcore/mesh.hpp>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

namespace rehearse::simcore::detail {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point3 = Kernel::Point_3;
using SurfaceMesh3 = CGAL::Surface_mesh<Point3>;

/// Builds an oriented Surface_mesh from the triangles with the given label (all when label < 0).
/// Returns false when the soup cannot be made a polygon mesh.
bool partToSurfaceMesh(const Mesh& m, int label, SurfaceMesh3& out);
}  // namespace rehearse::simcore::detail
