#include "point_file.h"

#include "cfl/error.h"

#include <cmath>
#include <cstdlib>
#include <istream>

namespace cfl::tool {

std::vector<Eigen::Vector3d> readPoints(std::istream& in, const std::string& source) {
  std::vector<Eigen::Vector3d> points;
  std::string line;
  long number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    for (char& c : line)
      if (c == ',' || c == '\t' || c == '\r') c = ' ';
    if (line.find_first_not_of(' ') == std::string::npos) continue;
    const auto fail = [&](const std::string& why) {
      throw Error(source + ":" + std::to_string(number) + ": " + why);
    };
    double xyz[3];
    int count = 0;
    const char* p = line.c_str();
    while (true) {
      while (*p == ' ') ++p;
      if (*p == '\0') break;
      char* end = nullptr;
      const double value = std::strtod(p, &end);
      if (end == p || (*end != ' ' && *end != '\0')) fail("expected three numbers x y z, got '" + line + "'");
      if (!std::isfinite(value)) fail("coordinate " + std::to_string(count + 1) + " is not finite");
      if (count == 3) fail("expected three numbers x y z, got more");
      xyz[count++] = value;
      p = end;
    }
    if (count != 3) fail("expected three numbers x y z, got " + std::to_string(count));
    points.emplace_back(xyz[0], xyz[1], xyz[2]);
  }
  if (in.bad()) throw Error(source + ": read error");
  return points;
}

}  // namespace cfl::tool
