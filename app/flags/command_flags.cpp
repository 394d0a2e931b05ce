#include "app/flags/command_flags.h"

#include <fmt/format.h>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/error.h"

namespace odvr::app {

CLI::Option* AddSetFlag(CLI::App* sub, const std::string& name, bool* value, bool set_to, const std::string& help) {
  return sub->add_flag_callback(
      name, [value, set_to] { *value = set_to; }, help);
}

CLI::Validator FiniteNumberIn(double min, double max) {
  const std::string range = fmt::format("[{:g}, {:g}]", min, max);
  return CLI::Validator(
      [min, max, range](std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value) || value < min || value > max)
          return "must be a number in " + range + ", got " + text;
        return "";
      },
      "NUMBER in " + range);
}

std::vector<double> ParseNumberList(const std::string& text, const std::string& flag) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size() || !std::isfinite(v.back())) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw UsageError(flag, "'" + item + "' is not a number (in '" + text + "')");
    }
  }
  return v;
}

int ConeRingsForCount(int cones) {
  switch (cones) {
    case 1:
      return 0;
    case 7:
      return 1;
    case 19:
      return 2;
    case 37:
      return 3;
    default:
      throw UsageError("--cones", "must be 1, 7, 19 or 37 (a centre cone and 0–3 hexagonal rings)");
  }
}

}  // namespace odvr::app
