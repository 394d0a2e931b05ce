#pragma once
// "WIDTHxHEIGHT" as options write an image or window size.
#include <string>
#include <utility>

namespace odvr {

// The two sides of "WIDTHxHEIGHT" (an 'x' or 'X' between, each 1 to 6 digits, at least 1x1).
// Throws UsageError naming `option` otherwise.
std::pair<int, int> ParseSize(const std::string& text, const std::string& option = "--size");

}  // namespace odvr
