#include "core/size_text.h"

#include "core/error.h"

namespace odvr {

std::pair<int, int> ParseSize(const std::string& text, const std::string& option) {
  const std::size_t x = text.find_first_of("xX");
  auto side = [&](std::size_t from, std::size_t to) {
    const std::string digits = text.substr(from, to - from);
    if (digits.empty() || digits.size() > 6 || digits.find_first_not_of("0123456789") != std::string::npos) return 0;
    return std::stoi(digits);
  };
  const int w = x == std::string::npos ? 0 : side(0, x), h = x == std::string::npos ? 0 : side(x + 1, text.size());
  if (w < 1 || h < 1) throw UsageError(option, "expects WIDTHxHEIGHT (at least 1x1), got '" + text + "'");
  return {w, h};
}

}  // namespace odvr
