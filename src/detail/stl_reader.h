#pragma once
// ASCII STL files read natively, in double precision (assimp parses them into 32-bit floats; binary STL
// stores floats, so assimp reads those exactly and keeps them).

#include "cfl/mesh.h"

#include <cstdint>
#include <string>

namespace cfl::detail {

// Whether a .stl file of `file_size` bytes that starts with `head` (its first 84 bytes or more) is ASCII
// STL: it starts with "solid" and its size is not that of a binary STL with the facet count of its header
// (binary files may start with "solid" too).
bool isAsciiStl(const std::string& head, std::uint64_t file_size);

// The facets of the ASCII STL `text` read from `path` (named in errors), in file order, over every solid:
// each facet's loop of vertices becomes a triangle (a loop of more than 3, which some writers emit, becomes
// consecutive triangles as MeshAssembler makes them); vertices with bit-identical positions are merged,
// numbered in order of first use. Normals are ignored.
// Throws cfl::Error "path: line N: ..." for a malformed number, a vertex with other than 3 coordinates, a
// loop with fewer than 3 vertices, a vertex outside a loop, or a line that is not an ASCII STL statement.
// Does not validate the result (see validateMesh) and does not refuse a file without facets.
TriangleMesh readAsciiStl(const std::string& path, const std::string& text);

}  // namespace cfl::detail
