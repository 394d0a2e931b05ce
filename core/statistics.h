#pragma once
// Order statistics of timings and errors: benches and players report medians, never means, on
// machines whose load comes and goes.
#include <vector>

namespace odvr {

// The median (the mean of the two middle values for an even count); 0 for none.
double Median(std::vector<double> values);

// The q-quantile, q in [0, 1], interpolated linearly between the order statistics at q (n − 1)
// (the median at q = 0.5; numpy's default); 0 for none.
double Quantile(std::vector<double> values, double q);

}  // namespace odvr
