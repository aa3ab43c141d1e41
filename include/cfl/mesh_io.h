#pragma once
/// @file
/// Reading triangle meshes from files: OBJ and ASCII STL natively, in double precision; binary STL, PLY,
/// OFF, glTF, Collada and every other format assimp reads through assimp. Part of the separate library
/// cfl::cfl_io, which links assimp; the core does not.

#include "cfl/mesh.h"

#include <string>

namespace cfl {

/// Reads every mesh of the file at `path` into one triangle soup, in the file's own unit and frame.
///
/// What you get:
/// - Every mesh of the scene, each placed by the accumulated transforms of the nodes that reference it (a
///   mesh referenced by two nodes appears twice). Point and line primitives are skipped.
/// - Polygons with n > 3 corners become n - 2 consecutive triangles with the polygon's orientation: a fan
///   from the first corner when convex, ear clipping in the polygon's plane when concave (a fan again when
///   the polygon is not simple, or has more than 256 corners).
/// - OBJ (by the extension .obj, any case): read by cfl itself. Triangle i is the i-th triangle of the file
///   after triangulation, whatever objects, groups and materials the faces sit in; corners in the file's
///   order; indices may be negative (relative) or name vertices defined further down; `p` and `l`
///   primitives and every non-geometric statement are skipped; a trailing backslash continues a line.
///   Coordinates are parsed to the nearest double, so the queries see the file's geometry exactly.
/// - ASCII STL (.stl starting with "solid" whose size is not a binary STL's): read by cfl itself, likewise
///   in double. Triangle i is the i-th facet of the file (over all its solids); keywords in any case;
///   normals ignored. Binary STL stores 32-bit floats and goes through assimp, which keeps them exactly.
/// - Other formats: triangles are numbered in scene order: nodes depth-first from the root, each node's meshes
///   in order, each mesh's faces in order. For a file holding one object with one material (the usual
///   STL, PLY or OFF), triangle i is therefore the i-th triangle of the file after triangulation, with its
///   corners in the file's order. Degenerate triangles (zero area, repeated corners) are kept as they are,
///   so these ids stay valid; they are harmless to every query (a degenerate triangle is a segment or a
///   point). No assimp post-processing step runs, since several of them drop or reorder triangles.
/// - Vertices with bit-identical positions are merged (STL stores none shared); vertex order is first use.
/// - Other formats' coordinates pass through assimp as 32-bit floats (assimp's own precision; its text parser
///   may also be one float ulp off the correctly rounded value), then widen to double: a vertex at 1000 may
///   move by 3e-5. For text formats where that matters, use OBJ or ASCII STL.
///
/// Throws cfl::Error whose message starts with the path and gives the reason: the file is missing or
/// unreadable, empty, an OBJ or ASCII STL line that is malformed (the message gives its number: a bad
/// number, a vertex with the wrong number of coordinates, a face or facet loop with fewer than 3 corners, an
/// OBJ index that is 0 or names no vertex, an STL line that is no STL statement),
/// not a format assimp can parse (with assimp's own message), holds no triangle, or has
/// a non-finite coordinate, or a face index out of range (except in OFF files, whose assimp reader clamps
/// such an index to the last vertex and only logs it), an OFF header whose vertex and face counts the file
/// is too small to hold, or a scene graph assimp left incomplete (a null child node, as its RAW reader does
/// for every object after the first). The result always passes validateMesh.
/// Thread safety: each call uses its own importer, so concurrent calls are safe. Time: linear in file size.
TriangleMesh loadMesh(const std::string& path);

}  // namespace cfl
