#pragma once
/// @file
/// Reading triangle meshes from files (OBJ, STL, PLY, OFF, glTF, Collada and every other format assimp
/// reads). Part of the separate library cfl::cfl_io, which links assimp; the core does not.

#include "cfl/mesh.h"

#include <string>

namespace cfl {

/// Reads every mesh of the file at `path` into one triangle soup, in the file's own unit and frame.
///
/// What you get:
/// - Every mesh of the scene, each placed by the accumulated transforms of the nodes that reference it (a
///   mesh referenced by two nodes appears twice). Point and line primitives are skipped.
/// - Polygons with more than three corners are triangulated by assimp into n - 2 triangles.
/// - Triangle ids: triangles are numbered in scene order: nodes depth-first from the root, each node's meshes
///   in order, each mesh's faces in order, an n-gon's triangles consecutively. For a file holding one object
///   with one material (the usual OBJ, STL, PLY or OFF), triangle i is therefore the i-th triangle of the file
///   after triangulation. Degenerate triangles (zero area, repeated corners) are kept as they are, so these
///   ids stay valid; they are harmless to every query (a degenerate triangle is a segment or a point).
/// - Vertices with bit-identical positions are merged (STL stores none shared); vertex order is first use.
/// - Coordinates pass through assimp as 32-bit floats (assimp's own precision), then widen to double.
///
/// Throws cfl::Error whose message starts with the path and gives the reason: the file is missing or
/// unreadable, empty, not a format assimp can parse (with assimp's own message), holds no triangle, or has
/// a non-finite coordinate. The result always passes validateMesh.
/// Thread safety: each call uses its own importer, so concurrent calls are safe. Time: linear in file size.
TriangleMesh loadMesh(const std::string& path);

}  // namespace cfl
