// Test helper: owns the SoA arrays of a shading batch and hands out RlfShadingBatch views.
#pragma once

#include <array>
#include <vector>

#include "runtime/abi.h"

namespace relief::compiler::testing {

struct TestBatch {
  explicit TestBatch(size_t n) : count(n) {
    for (auto* a : {&P, &N, &Ng, &dPdu, &dPdv, &dNdu, &dNdv, &Pout, &Nout})
      for (auto& c : *a) c.assign(n, 0.0f);
    for (auto* a : {&u, &v, &s, &t, &du, &dv, &dsdu, &dsdv, &dtdu, &dtdv}) a->assign(n, 0.0f);
    for (int m = 0; m < 6; ++m)
      for (int d = 0; d < 4; ++d) (&spaces.currentFromObject)[m][d * 5] = 1;
  }
  using Triple = std::array<std::vector<float>, 3>;

  // A view of points [first, first + n).
  RlfShadingBatch view(size_t first, size_t n, bool withNormalSeeds = true) {
    RlfShadingBatch b{};
    b.count = uint32_t(n);
    auto set = [&](RlfFloat3Array& out, Triple& in) {
      out = {in[0].data() + first, in[1].data() + first, in[2].data() + first};
    };
    set(b.P, P);
    set(b.N, N);
    set(b.Ng, Ng);
    set(b.dPdu, dPdu);
    set(b.dPdv, dPdv);
    if (withNormalSeeds) {
      set(b.dNdu, dNdu);
      set(b.dNdv, dNdv);
    }
    set(b.Pout, Pout);
    set(b.Nout, Nout);
    b.u = u.data() + first;
    b.v = v.data() + first;
    b.s = s.data() + first;
    b.t = t.data() + first;
    b.du = du.data() + first;
    b.dv = dv.data() + first;
    b.dsdu = dsdu.data() + first;
    b.dsdv = dsdv.data() + first;
    b.dtdu = dtdu.data() + first;
    b.dtdv = dtdv.data() + first;
    b.spaces = &spaces;
    return b;
  }
  RlfShadingBatch all() { return view(0, count); }

  size_t count;
  Triple P, N, Ng, dPdu, dPdv, dNdu, dNdv, Pout, Nout;
  std::vector<float> u, v, s, t, du, dv, dsdu, dsdv, dtdu, dtdv;
  RlfSpaces spaces{};
};

}  // namespace relief::compiler::testing
