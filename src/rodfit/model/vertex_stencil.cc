// The one instantiation of the vertex stencil's Hessian (vertex_stencil.h) with ceres::Jet over
// the 8 edge variables, kept out of the header so only this file pays for the Jet templates.
#include "rodfit/model/vertex_stencil.h"

#include <ceres/jet.h>

namespace rodfit {

void VertexHessianEdges(const VertexStencilConstants& c, const double* q, double* g8,
                        double* H8) {
  using Jet8 = ceres::Jet<double, 8>;
  const Vec3T<Jet8> e(Jet8(q[3] - q[0], 0), Jet8(q[4] - q[1], 1), Jet8(q[5] - q[2], 2));
  const Vec3T<Jet8> f(Jet8(q[6] - q[3], 3), Jet8(q[7] - q[4], 4), Jet8(q[8] - q[5], 5));
  Jet8 out[8];
  VertexGradientEdges<Jet8, true>(c, e, f, Jet8(q[9], 6), Jet8(q[10], 7), out);
  for (int a = 0; a < 8; ++a) {
    g8[a] = out[a].a;
    for (int b = 0; b < 8; ++b) H8[8 * a + b] = 0.5 * (out[a].v[b] + out[b].v[a]);
  }
}

}  // namespace rodfit
