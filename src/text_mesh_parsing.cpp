#include "detail/text_mesh_parsing.h"

#include <charconv>
#include <cmath>

namespace cfl::detail {

bool isTokenSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

std::string_view LineTokens::next() {
  while (position_ < line_.size() && isTokenSpace(line_[position_])) ++position_;
  const std::size_t begin = position_;
  if (begin < line_.size() && line_[begin] == '#') position_ = line_.size();
  while (position_ < line_.size() && !isTokenSpace(line_[position_])) ++position_;
  return line_.substr(begin, position_ - begin);
}

bool parseCoordinate(std::string_view token, double* value, std::string* problem) {
  std::string_view digits = token;
  if (!digits.empty() && digits[0] == '+') digits.remove_prefix(1);  // from_chars takes no '+'
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), *value);
  const std::string quoted = "'" + std::string(token) + "'";
  if (digits.empty() || error == std::errc::invalid_argument || end != digits.data() + digits.size()) {
    *problem = quoted + " is not a number";
    return false;
  }
  if (error == std::errc::result_out_of_range) {
    // Below the smallest double (a negative exponent) the nearest double is 0, harmless to any query;
    // beyond the largest there is none. from_chars leaves the value unset in both cases.
    const std::size_t exponent = digits.find_first_of("eE");
    if (exponent == std::string_view::npos || exponent + 1 >= digits.size() || digits[exponent + 1] != '-') {
      *problem = quoted + " is beyond the double range";
      return false;
    }
    *value = 0;
  }
  if (!std::isfinite(*value)) {
    *problem = quoted + " is not finite";
    return false;
  }
  return true;
}

}  // namespace cfl::detail
