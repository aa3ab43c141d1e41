#pragma once
// Wavefront OBJ files read natively, in double precision: assimp parses coordinates into 32-bit floats,
// which moves a vertex at 1000 by up to 3e-5, far beyond the 1e-9 of the diagonal that the queries are
// exact to.

#include "cfl/mesh.h"

#include <string>

namespace cfl::detail {

// The triangles of the OBJ text `text` read from `path` (named in errors), in file order: every `f` line's
// polygon becomes consecutive triangles (MeshAssembler), whatever the objects, groups and materials
// around it; vertices with bit-identical positions are merged, numbered in order of first use. Points and
// lines (`p`, `l`) and every other statement (texture coordinates, normals, groups, materials, ...) are
// skipped; `skipped_primitives` counts the points and lines.
// Throws cfl::Error "path: line N: ..." for a malformed number, a vertex with fewer than 3 coordinates or a
// non-finite one, a face with fewer than 3 corners, or a corner index that is 0 or names no vertex. Does not
// validate the result (see validateMesh) and does not refuse a file without triangles.
TriangleMesh readObj(const std::string& path, const std::string& text, std::size_t* skipped_primitives);

}  // namespace cfl::detail
