#include "detail/obj_reader.h"

#include "cfl/error.h"
#include "detail/mesh_assembly.h"
#include "detail/text_mesh_parsing.h"

#include <algorithm>
#include <charconv>
#include <cstdint>
#include <string_view>
#include <vector>

namespace cfl::detail {
namespace {

struct Reader {
  const std::string& path;
  std::size_t line_number = 0;  // of the logical line being read (its first physical line)

  [[noreturn]] void fail(const std::string& reason) const {
    throw Error(path + ": line " + std::to_string(line_number) + ": " + reason);
  }

  double number(std::string_view token, const char* what) const {
    double value = 0;
    std::string problem;
    if (!parseCoordinate(token, &value, &problem)) fail(std::string(what) + " " + problem);
    return value;
  }

  // The 0-based vertex a face corner names ("i", "i/t", "i//n" or "i/t/n"; negative i counts back from the
  // last vertex defined so far). The range is checked once the whole file is read: positive indices may
  // name vertices defined further down.
  std::int64_t corner(std::string_view token, std::int64_t vertices_so_far) const {
    const std::string_view index = token.substr(0, token.find('/'));
    std::int64_t value = 0;
    const auto [end, error] = std::from_chars(index.data(), index.data() + index.size(), value);
    if (index.empty() || error == std::errc::invalid_argument || end != index.data() + index.size()) {
      fail("face corner '" + std::string(token) + "' does not start with a vertex index");
    }
    if (error == std::errc::result_out_of_range) {
      fail("face corner '" + std::string(token) + "' has a vertex index beyond any vertex count");
    }
    if (value == 0) fail("face corner '" + std::string(token) + "' has vertex index 0 (OBJ counts from 1)");
    if (value < 0) {
      if (value < -vertices_so_far) {  // not -value, which overflows for the smallest int64
        fail("face corner '" + std::string(token) + "' counts back further than the " +
             std::to_string(vertices_so_far) + " vertices defined before it");
      }
      return vertices_so_far + value;
    }
    return value - 1;
  }
};

}  // namespace

TriangleMesh readObj(const std::string& path, const std::string& text, std::size_t* skipped_primitives) {
  Reader reader{path};
  std::vector<Eigen::Vector3d> positions;
  // Faces as runs of corner indices into `positions`, kept until the whole file is read.
  std::vector<std::int64_t> corners;
  std::vector<std::size_t> face_ends;
  std::vector<std::size_t> face_lines;
  std::size_t skipped = 0;

  std::string joined;  // a logical line continued over several physical ones (trailing '\')
  std::size_t position = 0, physical_line = 0;
  while (position < text.size()) {
    reader.line_number = physical_line + 1;
    std::string_view line;
    joined.clear();
    while (true) {
      const std::size_t end = std::min(text.find('\n', position), text.size());
      std::string_view piece(text.data() + position, end - position);
      position = end + 1;
      ++physical_line;
      while (!piece.empty() && isTokenSpace(piece.back())) piece.remove_suffix(1);
      if (piece.empty() || piece.back() != '\\' || position >= text.size()) {
        if (joined.empty()) {
          line = piece;
        } else {
          joined.append(piece);
          line = joined;
        }
        break;
      }
      joined.append(piece.substr(0, piece.size() - 1));
      joined.push_back(' ');
    }

    LineTokens tokens(line);
    const std::string_view keyword = tokens.next();
    if (keyword == "v") {
      Eigen::Vector3d p;
      for (int axis = 0; axis < 3; ++axis) {
        const std::string_view token = tokens.next();
        if (token.empty()) {
          reader.fail("vertex " + std::to_string(positions.size() + 1) + " has " + std::to_string(axis) +
                      " coordinates, needs 3");
        }
        p[axis] = reader.number(token, "coordinate");
      }
      positions.push_back(p);  // a w or a color after x y z is not geometry
    } else if (keyword == "f" || keyword == "fo") {
      std::size_t count = 0;
      for (std::string_view token = tokens.next(); !token.empty(); token = tokens.next()) {
        corners.push_back(reader.corner(token, std::int64_t(positions.size())));
        ++count;
      }
      if (count < 3) reader.fail("a face needs at least 3 corners, this one has " + std::to_string(count));
      face_ends.push_back(corners.size());
      face_lines.push_back(reader.line_number);
    } else if (keyword == "p" || keyword == "l") {
      ++skipped;
    }
  }

  MeshAssembler assembler;
  std::vector<int> ids(positions.size(), -1);  // merged vertex of each position, on first use
  std::vector<int> polygon;
  std::size_t begin = 0;
  for (std::size_t f = 0; f < face_ends.size(); ++f) {
    polygon.clear();
    for (std::size_t c = begin; c < face_ends[f]; ++c) {
      const std::int64_t v = corners[c];
      if (v >= std::int64_t(positions.size())) {
        reader.line_number = face_lines[f];
        reader.fail("a face refers to vertex " + std::to_string(v + 1) + ", but the file defines " +
                    std::to_string(positions.size()) + " (index out of range)");
      }
      if (ids[std::size_t(v)] < 0) ids[std::size_t(v)] = assembler.vertexId(positions[std::size_t(v)]);
      polygon.push_back(ids[std::size_t(v)]);
    }
    assembler.addPolygon(polygon);
    begin = face_ends[f];
  }
  if (skipped_primitives != nullptr) *skipped_primitives = skipped;
  return assembler.take();
}

}  // namespace cfl::detail
