#pragma once
// Mathematical constants, defined once (<numbers> is C++20; the project is C++17).

namespace odvr {

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace odvr
