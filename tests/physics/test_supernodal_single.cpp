// The single-precision supernodal solves against a dense twin: a hand-built supernodal factor (CHOLMOD's layout,
// with a permutation and padding between supernodes) whose values, rounded to float, define L exactly; the
// solve must be (P^T L L^T P)^-1 b to double round-off. And the refusals of a malformed factor, by message.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "physics/detail/supernodal_single.hpp"
#include "support/files.hpp"

namespace lumen::physics::detail {
namespace {

// A supernodal factor built column block by column block: each supernode's rows are its own columns, then a
// random subset of the rows after it; values random, with a dominant positive diagonal.
struct HandFactor {
  int n = 0;
  std::vector<int> super, pi, px, s, perm;
  std::vector<double> x;
  SupernodalView view() const {
    SupernodalView v;
    v.n = n;
    v.nsuper = static_cast<int>(super.size()) - 1;
    v.super = super.data();
    v.pi = pi.data();
    v.px = px.data();
    v.s = s.data();
    v.x = x.data();
    v.perm = perm.empty() ? nullptr : perm.data();
    return v;
  }
  // L as a dense matrix, from the values rounded to float over the largest diagonal entry (what
  // SupernodalSingle keeps), times that entry.
  Eigen::MatrixXd dense_rounded() const {
    double largest = 0.0;
    for (size_t k = 0; k + 1 < super.size(); ++k)
      for (int j = 0; j < super[k + 1] - super[k]; ++j)
        largest = std::max(largest, x[px[k] + j + j * (pi[k + 1] - pi[k])]);
    Eigen::MatrixXd L = Eigen::MatrixXd::Zero(n, n);
    for (size_t k = 0; k + 1 < super.size(); ++k) {
      const int nrow = pi[k + 1] - pi[k];
      for (int j = 0; j < super[k + 1] - super[k]; ++j)
        for (int i = j; i < nrow; ++i)
          L(s[pi[k] + i], super[k] + j) = largest * static_cast<float>(x[px[k] + i + j * nrow] / largest);
    }
    return L;
  }
};

HandFactor hand_factor(const std::vector<int>& sizes, bool permuted, std::mt19937& rng) {
  HandFactor f;
  f.n = std::accumulate(sizes.begin(), sizes.end(), 0);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::bernoulli_distribution keep(0.5);
  f.super = {0};
  f.pi = {0};
  f.px = {0};
  for (int size : sizes) {
    const int c0 = f.super.back(), c1 = c0 + size;
    for (int r = c0; r < c1; ++r) f.s.push_back(r);
    for (int r = c1; r < f.n; ++r)
      if (keep(rng)) f.s.push_back(r);
    const int nrow = static_cast<int>(f.s.size()) - f.pi.back();
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < nrow; ++i)
        f.x.push_back(i < j ? 0.0 : i == j ? 2.0 + value(rng) * 0.5 : value(rng) * 0.3);
    f.x.push_back(123.0);  // padding CHOLMOD may leave between supernodes: never read
    f.super.push_back(c1);
    f.pi.push_back(static_cast<int>(f.s.size()));
    f.px.push_back(static_cast<int>(f.x.size()));
  }
  if (permuted) {
    f.perm.resize(f.n);
    std::iota(f.perm.begin(), f.perm.end(), 0);
    std::shuffle(f.perm.begin(), f.perm.end(), rng);
  }
  return f;
}

// Supernodes of 6 columns (one block of four and a remainder of two), 1, 4 and 5 (the last with no rows below),
// with and without a permutation: the solve is the rounded factor's A^-1 b to round-off.
TEST(SupernodalSingle, SolvesTheRoundedFactorsSystemAsADenseTwin) {
  std::mt19937 rng(5);
  for (bool permuted : {false, true}) {
    const HandFactor f = hand_factor({6, 1, 4, 5}, permuted, rng);
    const SupernodalSingle single(f.view());
    ASSERT_EQ(single.n(), f.n);
    // A = P^T L L^T P with P the permutation (row k of L is row perm[k] of A).
    const Eigen::MatrixXd L = f.dense_rounded();
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(f.n, f.n);
    for (int k = 0; k < f.n; ++k) P(k, permuted ? f.perm[k] : k) = 1.0;
    const Eigen::MatrixXd A = P.transpose() * L * L.transpose() * P;
    std::normal_distribution<double> normal;
    Eigen::VectorXd b(f.n), x(f.n);
    for (int i = 0; i < f.n; ++i) b[i] = normal(rng);
    single.solve(b.data(), x.data());
    const Eigen::VectorXd twin = A.ldlt().solve(b);
    EXPECT_LE((x - twin).norm(), 1e-12 * twin.norm()) << "permuted " << permuted;
    EXPECT_LE((A * x - b).norm(), 1e-12 * b.norm());
  }
}

// A malformed factor is refused, naming the supernode, the row or the value.
TEST(SupernodalSingle, RefusesAMalformedFactorByName) {
  std::mt19937 rng(7);
  const auto message = [](const HandFactor& f) {
    return test::message_of<std::invalid_argument>([&] { SupernodalSingle single(f.view()); });
  };
  HandFactor f = hand_factor({3, 2}, false, rng);
  HandFactor g = f;
  g.s[1] = 2;  // supernode 0's second row is not its second column
  EXPECT_EQ(message(g), "SupernodalSingle: supernode 0: row 1 must be its own column 1, got 2");
  g = f;
  g.x[g.px[1]] = -1.0;  // supernode 1's first diagonal entry
  EXPECT_EQ(message(g), "SupernodalSingle: supernode 1: diagonal 0 must be > 0, got -1");
  g = f;
  g.s[g.pi[1] - 1] = 9;  // a row below supernode 0 past n = 5 (when it has one; else its last own row: refused too)
  EXPECT_NE(message(g).find("SupernodalSingle: supernode 0: row"), std::string::npos) << message(g);
  g = f;
  g.x[g.px[0] + 1] = 1e300;  // below the diagonal, outside float's range
  EXPECT_EQ(message(g).rfind("SupernodalSingle: value 1 must be finite and within float's range of the largest "
                             "diagonal entry, got 1", 0), 0u)
      << message(g);
  g = hand_factor({3, 2}, true, rng);
  g.perm[1] = g.perm[0];  // not a permutation
  EXPECT_EQ(message(g), "SupernodalSingle: perm[1] must be a row of [0, 5) not taken before, got " +
                            std::to_string(g.perm[0]));
  g = f;
  g.super.back() = 4;
  EXPECT_EQ(message(g), "SupernodalSingle: the supernodes must cover columns 0 to n = 5, got 0 to 4");
  EXPECT_EQ(message(HandFactor{}),
            "SupernodalSingle: the view must be a supernodal factor with n >= 1 and at least one supernode, got n "
            "= 0 and -1 supernodes");
}

}  // namespace
}  // namespace lumen::physics::detail
