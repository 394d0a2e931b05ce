#pragma once
// Order statistics of timings and errors: benches and players report medians, never means, on
// machines whose load comes and goes.
#include <vector>

namespace odvr {

// The median (the mean of the two middle values for an even count); 0 for none.
double Median(std::vector<double> values);

}  // namespace odvr
