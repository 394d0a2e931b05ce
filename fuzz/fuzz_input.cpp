#include "fuzz/fuzz_input.h"

#include <spdlog/spdlog.h>

namespace odvr::fuzz {

void QuietLogs() { spdlog::set_level(spdlog::level::off); }

}  // namespace odvr::fuzz
