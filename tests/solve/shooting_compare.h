// The discrete rod against the Kirchhoff shooting reference (rodfit/reference): the reference's
// clamp from a case's, and the largest vertex distance between a solution and the reference
// centre-line. Shared by the exact-reference tests and the stress table (tests/bench).
#pragma once

#include <algorithm>

#include "rodfit/reference/kirchhoff_shooting.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit::testing {

inline rodfit_reference::ClampSpec RefClamp(const Clamp& c) {
  rodfit_reference::ClampSpec r;
  r.position = c.position;
  r.tangent = c.tangent;
  r.normal = c.normal;
  return r;
}

/// Largest distance [m] between the discrete vertices and the reference centre-line at the same
/// rest arc lengths.
inline double MaxVertexError(const CaseSolution& sol, const rodfit_reference::ShootingResult& r) {
  double e = 0.0;
  for (int i = 0; i < sol.model->num_vertices(); ++i)
    e = std::max(e, (sol.state.x.col(i) - r.PositionAt(sol.model->arc_length(i))).norm());
  return e;
}

}  // namespace rodfit::testing
