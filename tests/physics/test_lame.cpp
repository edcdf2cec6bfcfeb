#include <gtest/gtest.h>
#include <cstdio>
#include "physics/lame.hpp"
namespace lumen::physics {
TEST(LameScratch, Print) {
  for (auto [a, l, r] : std::vector<std::array<int,3>>{{20,1,3},{40,1,6},{80,1,12},{160,1,24},{20,26,3},{80,2,12}}) {
    for (double nu : {0.3, 0.45}) {
      LameResult res = lame_error(a, l, r, 5000.0, nu, 100.0);
      printf("%d x %d x %d nu %.2f: l2 %.4f max %.4f tang %.2e axial %.2e nodes %d\n", a, l, r, nu, res.rel_l2_error, res.max_rel_error, res.max_tangential, res.max_axial, res.n_nodes);
    }
  }
}
}
