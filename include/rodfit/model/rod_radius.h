// The physical range of a rod's radius, checked wherever a radius is read (the experiment and
// scene YAML, profiles, exports; docs/formats.md, "Exports").
#pragma once

#include <cstdio>
#include <string>

namespace rodfit {

/// The range [m]: from a tenth of a micrometre (below any fibre a camera resolves) to a metre (far
/// beyond any surgical thread or tissue tube). Values outside are a unit or typing mistake, and
/// an export divides by r^4 (1e-300 m overflows) or multiplies by it (1e308 m overflows).
inline constexpr double kMinRodRadius = 1e-7;
inline constexpr double kMaxRodRadius = 1.0;

/// Empty when `radius` [m] is a rod radius rodfit takes for a rod of `length` [m]: in
/// [kMinRodRadius, kMaxRodRadius] and at most the length (a rod is longer than it is thick);
/// otherwise the reason, one line without the key (the reader names the file and key).
inline std::string CheckRodRadius(double radius, double length) {
  auto show = [](double v) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", v);
    return std::string(text);
  };
  if (!(radius >= kMinRodRadius && radius <= kMaxRodRadius))
    return show(radius) + " m is outside the physical range [" + show(kMinRodRadius) + ", " +
           show(kMaxRodRadius) + "] m";
  if (radius > length)
    return show(radius) + " m is more than the rod's length " + show(length) +
           " m (a rod is longer than it is thick)";
  return "";
}

}  // namespace rodfit
