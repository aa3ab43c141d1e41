#pragma once
// Pieces the native text mesh readers (OBJ, ASCII STL) share: whitespace tokens of a line and coordinates
// parsed to the nearest double.

#include <string>
#include <string_view>

namespace cfl::detail {

// The whitespace-separated tokens of one line, up to a token starting with '#' (a comment).
class LineTokens {
 public:
  explicit LineTokens(std::string_view line) : line_(line) {}
  // The next token, or an empty view at the end.
  std::string_view next();

 private:
  std::string_view line_;
  std::size_t position_ = 0;
};

// Whether c separates tokens (space, tab, CR, FF, VT).
bool isTokenSpace(char c);

// `token` as the nearest double (an optional leading '+'; locale-independent). On failure returns false and
// sets `problem` to why, quoting the token: not a number, beyond the double range, or not finite. A value
// below the smallest double becomes 0, its nearest double.
bool parseCoordinate(std::string_view token, double* value, std::string* problem);

}  // namespace cfl::detail
