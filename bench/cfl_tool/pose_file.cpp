#include "pose_file.h"

#include "cfl/cfl_query.h"
#include "cfl/error.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>

namespace cfl::tool {
namespace {

[[noreturn]] void lineError(const std::string& source, long line, const std::string& reason) {
  throw Error(source + ":" + std::to_string(line) + ": " + reason);
}

// Splits at spaces, tabs and commas; consecutive separators count as one, so "1, 2" and "1,2" both work.
std::vector<std::string> splitWords(const std::string& text) {
  std::vector<std::string> words;
  std::string word;
  for (char c : text) {
    if (c == ' ' || c == '\t' || c == ',' || c == '\r') {
      if (!word.empty()) words.push_back(std::move(word));
      word.clear();
    } else {
      word += c;
    }
  }
  if (!word.empty()) words.push_back(std::move(word));
  return words;
}

bool parseFinite(const std::string& word, double* value) {
  errno = 0;
  char* end = nullptr;
  *value = std::strtod(word.c_str(), &end);
  return !word.empty() && end == word.c_str() + word.size() && std::isfinite(*value);
}

std::string formatDouble(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", v);
  return buffer;
}

// CSV fields: split at commas only; a field may not be empty.
std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return fields;
}

}  // namespace

std::vector<Eigen::Isometry3d> readPoses(std::istream& in, const std::string& source) {
  std::vector<Eigen::Isometry3d> poses;
  std::string line;
  for (long line_number = 1; std::getline(in, line); ++line_number) {
    if (auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    const std::vector<std::string> words = splitWords(line);
    if (words.empty()) continue;
    if (words.size() != 12) {
      lineError(source, line_number,
                "expected 12 numbers (the row-major 3x4 matrix [R | t]), found " + std::to_string(words.size()));
    }
    double m[12];
    for (int i = 0; i < 12; ++i) {
      if (!parseFinite(words[i], &m[i])) {
        lineError(source, line_number, "number " + std::to_string(i + 1) + " ('" + words[i] + "') is not a finite number");
      }
    }
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) X.linear()(r, c) = m[4 * r + c];
      X.translation()(r) = m[4 * r + 3];
    }
    const std::string what = source + ":" + std::to_string(line_number) + ": the pose";
    validatePose(X, what.c_str());
    poses.push_back(X);
  }
  if (in.bad()) throw Error(source + ": read error");
  return poses;
}

std::string formatPose(const Eigen::Isometry3d& X) {
  std::string out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (!out.empty()) out += ' ';
      out += formatDouble(c < 3 ? X.linear()(r, c) : X.translation()(r));
    }
  }
  return out;
}

std::string formatDistanceRow(const DistanceRow& row) {
  std::string out = std::to_string(row.pose) + "," + formatDouble(row.distance);
  for (int i = 0; i < 3; ++i) out += "," + formatDouble(row.point_a[i]);
  for (int i = 0; i < 3; ++i) out += "," + formatDouble(row.point_b[i]);
  char micros[48];
  std::snprintf(micros, sizeof micros, "%.3f", row.micros);
  out += "," + std::to_string(row.triangle_a) + "," + std::to_string(row.triangle_b) + "," + micros;
  if (!row.method.empty()) out += "," + row.method;
  return out;
}

std::vector<DistanceRow> readDistanceCsv(std::istream& in, const std::string& source) {
  std::string line;
  if (!std::getline(in, line)) throw Error(source + ":1: missing header line '" + std::string(kDistanceCsvHeader) + "'");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const std::string header = kDistanceCsvHeader;
  bool with_method = false;
  if (line == header + ",method") {
    with_method = true;
  } else if (line != header) {
    lineError(source, 1, "header is '" + line + "', expected '" + header + "' (optionally followed by ',method')");
  }
  const std::size_t field_count = with_method ? 12 : 11;
  std::vector<DistanceRow> rows;
  for (long line_number = 2; std::getline(in, line); ++line_number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string> fields = splitCsv(line);
    if (fields.size() != field_count) {
      lineError(source, line_number,
                "expected " + std::to_string(field_count) + " fields, found " + std::to_string(fields.size()));
    }
    double numbers[11];
    for (int i = 0; i < 11; ++i) {
      if (!parseFinite(fields[i], &numbers[i])) {
        lineError(source, line_number, "field " + std::to_string(i + 1) + " ('" + fields[i] + "') is not a finite number");
      }
    }
    auto integer = [&](int i) {
      if (numbers[i] != std::floor(numbers[i]) || std::abs(numbers[i]) > 2e9) {
        lineError(source, line_number, "field " + std::to_string(i + 1) + " ('" + fields[i] + "') is not an integer");
      }
      return long(numbers[i]);
    };
    DistanceRow row;
    row.pose = integer(0);
    row.distance = numbers[1];
    row.point_a = Eigen::Vector3d(numbers[2], numbers[3], numbers[4]);
    row.point_b = Eigen::Vector3d(numbers[5], numbers[6], numbers[7]);
    row.triangle_a = int(integer(8));
    row.triangle_b = int(integer(9));
    row.micros = numbers[10];
    // The distance may be negative: `cfl distance --signed` reports minus the penetration depth.
    if (row.pose < 0 || row.micros < 0) {
      lineError(source, line_number, "pose index and micros must be >= 0");
    }
    if (with_method) {
      row.method = fields[11];
      if (row.method != "cfl" && row.method != "obbrss") {
        lineError(source, line_number, "method '" + row.method + "' is neither 'cfl' nor 'obbrss'");
      }
    }
    rows.push_back(std::move(row));
  }
  if (in.bad()) throw Error(source + ": read error");
  return rows;
}

}  // namespace cfl::tool
