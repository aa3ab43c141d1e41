#include "detail/stl_reader.h"

#include "cfl/error.h"
#include "detail/mesh_assembly.h"
#include "detail/text_mesh_parsing.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <string_view>
#include <vector>

namespace cfl::detail {
namespace {

bool sameKeyword(std::string_view token, std::string_view keyword) {
  return token.size() == keyword.size() &&
         std::equal(token.begin(), token.end(), keyword.begin(),
                    [](char a, char b) { return std::tolower(static_cast<unsigned char>(a)) == b; });
}

}  // namespace

bool isAsciiStl(const std::string& head, std::uint64_t file_size) {
  if (head.size() >= 84) {
    const auto byte = [&](std::size_t i) { return std::uint64_t(static_cast<unsigned char>(head[i])); };
    const std::uint64_t facets = byte(80) | byte(81) << 8 | byte(82) << 16 | byte(83) << 24;
    if (file_size == 84 + 50 * facets) return false;
  }
  const std::size_t line_end = std::min(head.find('\n'), head.size());
  return sameKeyword(LineTokens(std::string_view(head).substr(0, line_end)).next(), "solid");
}

TriangleMesh readAsciiStl(const std::string& path, const std::string& text) {
  std::size_t line_number = 0;
  auto fail = [&](const std::string& reason) {
    throw Error(path + ": line " + std::to_string(line_number) + ": " + reason);
  };
  MeshAssembler assembler;
  std::vector<int> loop;
  bool in_loop = false;
  std::size_t position = 0;
  while (position < text.size()) {
    const std::size_t end = std::min(text.find('\n', position), text.size());
    LineTokens tokens(std::string_view(text.data() + position, end - position));
    position = end + 1;
    ++line_number;
    const std::string_view keyword = tokens.next();
    if (keyword.empty()) continue;
    if (sameKeyword(keyword, "vertex")) {
      if (!in_loop) fail("a vertex outside an 'outer loop'");
      Eigen::Vector3d p;
      int count = 0;
      for (std::string_view token = tokens.next(); !token.empty(); token = tokens.next(), ++count) {
        std::string problem;
        if (count < 3 && !parseCoordinate(token, &p[count], &problem)) fail("coordinate " + problem);
      }
      if (count != 3) fail("a vertex has " + std::to_string(count) + " coordinates, needs 3");
      loop.push_back(assembler.vertexId(p));
    } else if (sameKeyword(keyword, "outer")) {
      if (in_loop) fail("an 'outer loop' inside another");
      in_loop = true;
      loop.clear();
    } else if (sameKeyword(keyword, "endloop")) {
      if (!in_loop) fail("'endloop' without 'outer loop'");
      if (loop.size() < 3) fail("a facet's loop has " + std::to_string(loop.size()) + " vertices, needs 3");
      assembler.addPolygon(loop);
      in_loop = false;
    } else if (!(sameKeyword(keyword, "solid") || sameKeyword(keyword, "endsolid") ||
                 sameKeyword(keyword, "facet") || sameKeyword(keyword, "endfacet"))) {
      fail("'" + std::string(keyword.substr(0, 40)) + "' is not an ASCII STL statement");
    }
  }
  if (in_loop) fail("the file ends inside a facet's loop");
  return assembler.take();
}

}  // namespace cfl::detail
