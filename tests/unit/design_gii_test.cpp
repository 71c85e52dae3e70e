// GII (004 eq 11), axis-angle sampling (eq 14–16), culling vs exhaustive search, Twin-Pantograph problem.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

#include "phalanx/host/design/gii.h"
#include "phalanx/host/design/pen_gii.h"
#include "phalanx/pen/kinematics.h"

namespace d = phalanx::host::design;
namespace pen = phalanx::pen;

namespace {
constexpr double kPi = 3.14159265358979323846;

Eigen::MatrixXd planar2R(double l1, double l2, double q1, double q2) {
  Eigen::MatrixXd J(2, 2);
  J << -l1 * std::sin(q1) - l2 * std::sin(q1 + q2), -l2 * std::sin(q1 + q2),
      l1 * std::cos(q1) + l2 * std::cos(q1 + q2), l2 * std::cos(q1 + q2);
  return J;
}

/// Closed-form singular values of the planar 2R Jacobian: σ² are the roots of λ² − Tλ + D = 0 with
/// T = ‖J‖_F² = l1² + 2 l2² + 2 l1 l2 cos q2 and D = det² = (l1 l2 sin q2)².
std::pair<double, double> planar2RSigmas(double l1, double l2, double q2) {
  const double T = l1 * l1 + 2 * l2 * l2 + 2 * l1 * l2 * std::cos(q2);
  const double D = std::pow(l1 * l2 * std::sin(q2), 2);
  const double disc = std::sqrt(std::max(0.0, T * T - 4 * D));
  return {std::sqrt((T - disc) / 2), std::sqrt((T + disc) / 2)};
}
}  // namespace

TEST(DesignGii, Planar2RGiiEqualsTheClosedFormOverAWorkspace) {
  const double l1 = 0.3, l2 = 0.2;
  std::vector<std::pair<double, double>> qs;
  for (int i = 0; i < 7; ++i)
    for (int k = 0; k < 9; ++k) qs.push_back({-1.0 + 0.3 * i, 0.4 + 0.25 * k});
  const double g = d::gii([&](std::size_t s) { return planar2R(l1, l2, qs[s].first, qs[s].second); }, qs.size(),
                          Eigen::Vector2d(1, 1), Eigen::Vector2d(1, 1));
  double lo = 1e9, hi = 0;
  for (const auto& q : qs) {
    const auto s = planar2RSigmas(l1, l2, q.second);
    lo = std::min(lo, s.first), hi = std::max(hi, s.second);
  }
  EXPECT_NEAR(g, lo / hi, 1e-12);
  EXPECT_GT(g, 0.0);
  EXPECT_LT(g, 1.0);
}

TEST(DesignGii, Planar2RIsIsotropicAtL1EqualsSqrt2L2And135Degrees) {
  // Classic result: J is isotropic for l1 = √2 l2 at q2 = ±135°, whatever q1.
  const double l2 = 0.1, l1 = std::sqrt(2.0) * l2;
  for (double q1 : {-0.7, 0.0, 1.1}) {
    const double g = d::gii([&](std::size_t) { return planar2R(l1, l2, q1, 3 * kPi / 4); }, 1,
                            Eigen::Vector2d(1, 1), Eigen::Vector2d(1, 1));
    EXPECT_NEAR(g, 1.0, 1e-12);
  }
  // Any other elbow angle is not isotropic.
  const double g = d::gii([&](std::size_t) { return planar2R(l1, l2, 0.0, kPi / 2); }, 1, Eigen::Vector2d(1, 1),
                          Eigen::Vector2d(1, 1));
  EXPECT_LT(g, 0.9);
}

TEST(DesignGii, GiiIsInvariantToUniformScalingAndFollowsTaskScaling) {
  const double l1 = 0.3, l2 = 0.2;
  auto J = [&](std::size_t s) {
    const double x = static_cast<double>(s);
    return planar2R(l1, l2, 0.2 * x, 0.5 + 0.3 * x);
  };
  const double g = d::gii(J, 5, Eigen::Vector2d(1, 1), Eigen::Vector2d(1, 1));
  EXPECT_NEAR(d::gii(J, 5, Eigen::Vector2d(3, 3), Eigen::Vector2d(1, 1)), g, 1e-12);
  EXPECT_NEAR(d::gii(J, 5, Eigen::Vector2d(1, 1), Eigen::Vector2d(7, 7)), g, 1e-12);
  // Non-uniform S_T changes the result, and equals the SVD of S_J J S_T⁻¹ by hand.
  const Eigen::Vector2d st(1.0, 2.5);
  double lo = 1e9, hi = 0;
  for (std::size_t s = 0; s < 5; ++s) {
    const Eigen::MatrixXd A = J(s) * st.cwiseInverse().asDiagonal();
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
    lo = std::min(lo, svd.singularValues().minCoeff()), hi = std::max(hi, svd.singularValues().maxCoeff());
  }
  EXPECT_NEAR(d::gii(J, 5, Eigen::Vector2d(1, 1), st), lo / hi, 1e-12);
}

TEST(DesignGii, AxisAngleSampleCountsFollowEq16) {
  const double t45 = kPi / 4;
  // §IV: "for θ̄1 = 45°, K_r can be chosen from {6, 8, 34, 58, …} for N = {1, 2, 3, 4, …}". Eq 16 gives 18 for
  // N = 2 (1 + floor(16 sin 22.5°) + floor(16 sin 45°) = 1 + 6 + 11); the printed 8 has lost its leading 1.
  EXPECT_EQ(d::axisAngleSampleCount(t45, 1), 6u);
  EXPECT_EQ(d::axisAngleSampleCount(t45, 2), 18u);
  EXPECT_EQ(d::axisAngleSampleCount(t45, 3), 34u);
  EXPECT_EQ(d::axisAngleSampleCount(t45, 4), 58u);
  // Table VI: 617 orientations for ±45°.
  EXPECT_EQ(d::axisAngleSampleCount(t45, 14), 617u);
  // Eq 15 with the full ±8 × ±5 × ±5 cm grid at 0.5 cm (33·21·21 = 14553, d_r/d_t = 2/3 → k_r = 596) → N = 14.
  EXPECT_EQ(d::ringsForTranslationalSamples(t45, 33.0 * 21 * 21, 2, 3), 14u);
  for (std::size_t N : {1u, 3u, 14u}) {
    const auto s = d::axisAngleSamples(t45, N);
    EXPECT_EQ(s.size(), d::axisAngleSampleCount(t45, N));
    for (const auto& x : s) {
      EXPECT_LE(x.tip_rad, t45 + 1e-12);
      EXPECT_GE(x.azimuth_rad, 0.0);
      EXPECT_LT(x.azimuth_rad, 2 * kPi);
    }
  }
}

TEST(DesignGii, AxisAngleSamplesAreNearlyUniformOnTheCap) {
  // Eq 14's aim: neighbouring samples on a ring are about Δθ1 apart (arc length on the unit sphere).
  const double t45 = kPi / 4;
  const std::size_t N = 14;
  const auto s = d::axisAngleSamples(t45, N);
  const double dt1 = t45 / N;
  for (std::size_t i = 1; i + 1 < s.size(); ++i) {
    if (s[i + 1].tip_rad != s[i].tip_rad) continue;
    const double arc = std::sin(s[i].tip_rad) * (s[i + 1].azimuth_rad - s[i].azimuth_rad);
    EXPECT_GE(arc, 0.99 * dt1);
    EXPECT_LE(arc, 1.25 * dt1);
  }
}

namespace {
/// Random σ tables with ties and infeasible samples, to test the search logic alone.
class RandomProblem final : public d::MinimaxProblem {
 public:
  RandomProblem(std::size_t groups, std::size_t members, std::size_t samples, unsigned seed)
      : g_(groups), m_(members), s_(samples), table_(groups * members * samples) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (auto& e : table_) {
      // Quantised to 1/16 so that ties are frequent; 3 % infeasible (σ_min = 0).
      const double a = std::round(u(rng) * 16) / 16 + 0.0625, b = std::round(u(rng) * 16) / 16 + 0.0625;
      e = {std::min(a, b), std::max(a, b)};
      if (u(rng) < 0.03) e.min = 0;
    }
  }
  std::size_t numGroups() const override { return g_; }
  std::size_t groupSize() const override { return m_; }
  std::size_t numSamples() const override { return s_; }
  void evaluate(std::size_t group, std::size_t sample, const std::uint32_t* members, std::size_t n,
                d::SigmaPair* out) const override {
    for (std::size_t i = 0; i < n; ++i) out[i] = table_[((group * m_) + members[i]) * s_ + sample];
  }

 private:
  std::size_t g_, m_, s_;
  std::vector<d::SigmaPair> table_;
};
}  // namespace

TEST(DesignGii, CullingReturnsTheExhaustiveOptimumOnRandomProblems) {
  for (unsigned seed = 1; seed <= 60; ++seed) {
    std::mt19937 rng(seed);
    const std::size_t groups = 1 + rng() % 40, members = 1 + rng() % 6, samples = 1 + rng() % 50;
    const RandomProblem pb(groups, members, samples, seed);
    for (unsigned threads : {1u, 2u}) {
      d::SearchOptions o;
      o.threads = threads;
      const d::SearchResult ex = d::exhaustiveSearch(pb, o);
      const d::SearchResult cu = d::cullingSearch(pb, o);
      ASSERT_EQ(cu.best, ex.best) << "seed " << seed << " threads " << threads;
      ASSERT_EQ(cu.gii, ex.gii) << "seed " << seed;
      EXPECT_EQ(ex.jacobian_evals, groups * samples);
    }
  }
}

namespace {
/// A problem whose evaluations wait until the search's progress callback has run once: a report that came only
/// between rounds or passes could never release them (the wait is bounded, so that such a build fails, not hangs).
class HeldUntilReported final : public d::MinimaxProblem {
 public:
  explicit HeldUntilReported(const d::MinimaxProblem& inner) : inner_(inner) {}
  std::size_t numGroups() const override { return inner_.numGroups(); }
  std::size_t groupSize() const override { return inner_.groupSize(); }
  std::size_t numSamples() const override { return inner_.numSamples(); }
  void evaluate(std::size_t group, std::size_t sample, const std::uint32_t* members, std::size_t n,
                d::SigmaPair* out) const override {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!reported.load() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    inner_.evaluate(group, sample, members, n, out);
  }
  mutable std::atomic<bool> reported{false};

 private:
  const d::MinimaxProblem& inner_;
};
}  // namespace

TEST(DesignGii, ProgressIsReportedInsideAPassAndDoesNotChangeTheResult) {
  const RandomProblem inner(30, 4, 40, 7);
  for (bool culling : {true, false}) {
    HeldUntilReported pb(inner);
    std::vector<d::SearchProgress> reports;
    std::mutex m;
    d::SearchOptions o;
    o.progress_s = 0.01;
    o.progress = [&](const d::SearchProgress& p) {
      std::lock_guard<std::mutex> lock(m);
      reports.push_back(p);
      pb.reported = true;
    };
    const d::SearchResult r = culling ? d::cullingSearch(pb, o) : d::exhaustiveSearch(pb, o);
    const d::SearchResult quiet = culling ? d::cullingSearch(inner) : d::exhaustiveSearch(inner);
    EXPECT_EQ(r.best, quiet.best);
    EXPECT_EQ(r.gii, quiet.gii);
    std::lock_guard<std::mutex> lock(m);
    ASSERT_FALSE(reports.empty());
    const d::SearchProgress& first = reports.front();
    EXPECT_STREQ(first.search, culling ? "culling" : "exhaustive");
    EXPECT_EQ(first.round, 0u) << "the first report came before any round ended";
    EXPECT_GE(first.fraction, 0.0);
    EXPECT_LT(first.fraction, 1.0) << "inside the first pass";
    EXPECT_EQ(first.candidates, 120u);
    if (culling) {
      EXPECT_STREQ(first.pass, "all alive at a sample");
    }
    for (const d::SearchProgress& p : reports) EXPECT_LE(p.fraction, 1.0);
  }
}

TEST(DesignGii, CullingHandlesAnAllInfeasibleProblem) {
  class Zero final : public d::MinimaxProblem {
   public:
    std::size_t numGroups() const override { return 7; }
    std::size_t groupSize() const override { return 3; }
    std::size_t numSamples() const override { return 5; }
    void evaluate(std::size_t, std::size_t, const std::uint32_t*, std::size_t n, d::SigmaPair* out) const override {
      for (std::size_t i = 0; i < n; ++i) out[i] = {0.0, 1.0};
    }
  } pb;
  const d::SearchResult ex = d::exhaustiveSearch(pb), cu = d::cullingSearch(pb);
  EXPECT_EQ(ex.best, 0u);
  EXPECT_EQ(cu.best, 0u);
  EXPECT_EQ(cu.gii, 0.0);
}

namespace {
d::PenGiiSpec smallPenSpec() {
  d::PenGiiSpec s;
  s.l1 = {2.4, 4.4, 1.0};
  s.l2 = {14.0, 20.0, 3.0};
  s.l3 = {20.0, 26.0, 3.0};
  s.l6 = {7.0, 9.0, 2.0};
  s.q1 = {1.0, 2.0, 0.5};
  s.wi = {0.0, 8.0, 8.0};
  s.wj = {0.0, 5.0, 5.0};
  s.wk = {-5.0, 5.0, 10.0};
  s.rings = 1;
  return s;
}
}  // namespace

TEST(DesignGii, TwinPantographProblemHasTheTableViiSizes) {
  const d::PenGiiSpec paper;  // defaults = Tables VI and VII
  EXPECT_EQ(paper.l1.count() * paper.l2.count() * paper.l3.count() * paper.l6.count() * paper.q1.count(),
            22027824u);
  const d::TwinPantographGii small(smallPenSpec());
  EXPECT_EQ(small.numOrientations(), 6u);
  EXPECT_EQ(small.numPositions(), 8u);
  EXPECT_EQ(small.numCandidates(), 3u * 3 * 3 * 2 * 3);
}

TEST(DesignGii, TwinPantographGramEvaluationEqualsTheSvdOfTheScaledJacobian) {
  const d::TwinPantographGii pb(smallPenSpec());
  std::vector<std::uint32_t> members{0, 1, 2};
  std::vector<d::SigmaPair> out(3);
  std::size_t checked = 0;
  for (std::size_t g = 0; g < pb.numGroups(); g += 5) {
    for (std::size_t s = 0; s < pb.numSamples(); s += 7) {
      pb.evaluate(g, s, members.data(), 3, out.data());
      for (std::size_t m = 0; m < 3; ++m) {
        Eigen::Matrix<double, 6, 5> A;
        const bool ok = pb.scaledJacobian(pb.design(g * 3 + m), s, A);
        if (!ok) {
          EXPECT_EQ(out[m].min, 0.0);
          continue;
        }
        const d::SigmaPair ref = d::sigmaBounds(A);
        EXPECT_NEAR(out[m].max, ref.max, 1e-9 * ref.max);
        EXPECT_NEAR(out[m].min, ref.min, 1e-6 * ref.max);
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 20u);
}

TEST(DesignGii, TwinPantographJacobianHasTheSymmetriesOfTheHomePose) {
  d::PenGiiSpec s = smallPenSpec();
  s.l1 = {2.4, 2.4, 1}, s.l2 = {17, 17, 1}, s.l3 = {23, 23, 1}, s.l6 = {7, 7, 1}, s.q1 = {1, 1, 1};
  s.wi = {0, 0, 1}, s.wj = {0, 0, 1}, s.wk = {0, 0, 1};
  s.rings = 1;
  const d::TwinPantographGii pb(s);
  Eigen::Matrix<double, 6, 5> A;
  ASSERT_TRUE(pb.scaledJacobian(pb.design(0), 0, A));  // centre, home orientation: pen frame = base frame
  // Lateral motion (i) does not turn the waists (rows 0 and 3: q1, q4).
  EXPECT_NEAR(A(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(A(3, 0), 0.0, 1e-12);
  // Motion along the pen (j) turns both waists alike; depth (k) turns them oppositely (ends at y = ∓7 cm,
  // waist axes at ∓4 cm: each end sits 3 cm outside its waist axis, mirrored about the centre).
  EXPECT_GT(std::fabs(A(0, 1)), 0.0);
  EXPECT_NEAR(A(0, 1), A(3, 1), 1e-12);
  EXPECT_NEAR(A(0, 2), -A(3, 2), 1e-12);
  // Lateral motion moves the two five-bars identically (rows 1, 2 vs 4, 5).
  EXPECT_NEAR(A(1, 0), A(4, 0), 1e-12);
  EXPECT_NEAR(A(2, 0), A(5, 0), 1e-12);
}

TEST(DesignGii, CullingReturnsTheExhaustiveOptimumOnASmallPenProblemWithFewerEvaluations) {
  const d::TwinPantographGii pb(smallPenSpec());
  const d::SearchResult ex = d::exhaustiveSearch(pb), cu = d::cullingSearch(pb);
  EXPECT_EQ(cu.best, ex.best);
  EXPECT_EQ(cu.gii, ex.gii);
  EXPECT_GT(ex.gii, 0.0);
  EXPECT_LT(cu.jacobian_evals, ex.jacobian_evals);
  // And the optimum's GII equals the independent SVD-based evaluation.
  EXPECT_NEAR(d::penGii(pb, pb.design(ex.best)), ex.gii, 1e-6 * ex.gii);
}

TEST(DesignGii, VelocityModeScalesTheSameJacobianByEq27AndForceModeByEq19) {
  d::PenGiiSpec f = smallPenSpec();
  d::PenGiiSpec v = f;
  v.mode = d::PenGiiMode::kVelocity;
  const d::TwinPantographGii pf(f), pv(v);
  const d::PenDesign des{2.4, 17.0, 23.0, 7.0, 1.6};
  Eigen::Matrix<double, 5, 1> ratio;  // (S_T,vel) / (S_T,force)⁻¹ column by column
  ratio << 1.0, 1.0, 1.5, 3.6 * 0.06, 3.9 * 0.06;
  std::size_t checked = 0;
  for (std::size_t s = 0; s < pf.numSamples(); ++s) {
    Eigen::Matrix<double, 6, 5> Af, Av;
    if (!pf.scaledJacobian(des, s, Af)) continue;
    ASSERT_TRUE(pv.scaledJacobian(des, s, Av));
    EXPECT_LE((Af * ratio.asDiagonal() - Av).norm(), 1e-12 * Af.norm());
    ++checked;
  }
  EXPECT_GT(checked, 10u);
}

TEST(DesignGii, PenProblemUsesTheControllersPenModel) {
  // One definition of the geometry: the GII's Jacobian of Table VII's design at the workspace centre (home
  // orientation) equals the one built from pen::makeModel + computeForward, the controller's model (l6 = pen
  // centre → universal joint, pen length 2·l6). Lengths in cm on both sides (the kinematics are scale-free).
  d::PenGiiSpec s;
  s.l1 = {2.4, 2.4, 1}, s.l2 = {17, 17, 1}, s.l3 = {23, 23, 1}, s.l6 = {7, 7, 1}, s.q1 = {1, 1, 1};
  s.wi = {0, 0, 1}, s.wj = {0, 0, 1}, s.wk = {0, 0, 1};
  s.rings = 1;
  s.distance_cm = 25.0;
  const d::TwinPantographGii pb(s);
  ASSERT_EQ(pb.numPositions(), 1u);
  Eigen::Matrix<double, 6, 5> A;
  ASSERT_TRUE(pb.scaledJacobian({2.4, 17.0, 23.0, 7.0, 1.0}, pb.seedSample(), A));
  pen::Model<double> m;
  ASSERT_EQ(pen::makeModel<double>({2.4, 17.0, 23.0, 8.0, 7.0, 25.0}, m), pen::Status::kOk);
  pen::Data<double> kin;
  ASSERT_TRUE(pen::isUsable(pen::computeForward(m, m.q_home_rad, kin)));
  EXPECT_NEAR(kin.length_m, 14.0, 1e-9);
  const double st_inv[5] = {1.0, 1.0, 1.0 / 1.5, 1.0 / 3.6, 1.0 / 3.9};  // force S_T⁻¹ (eq 19)
  for (int k = 0; k < 5; ++k) {
    // Unit twist k at the centre: translation e_k (k < 3) or rotation about i (k = 3) / k (k = 4), applied to
    // each end through its measured position p_end − c.
    for (std::size_t e = 0; e < 2; ++e) {
      const auto& pd = kin.pantograph[e];
      pen::Vec3<double> v{0, 0, 0};
      if (k < 3) {
        v[static_cast<std::size_t>(k)] = 1.0;
      } else {
        pen::Vec3<double> w{0, 0, 0};
        w[k == 3 ? 0 : 2] = 1.0;
        const pen::Vec3<double> r{pd.B_p_tip[0] - kin.B_p_centre[0], pd.B_p_tip[1] - kin.B_p_centre[1],
                                  pd.B_p_tip[2] - kin.B_p_centre[2]};
        v = pen::cross(w, r);
      }
      Eigen::Matrix3d J;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) J(r, c) = pd.J[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
      const Eigen::Vector3d qd = J.inverse() * Eigen::Vector3d(v[0], v[1], v[2]);
      for (int r = 0; r < 3; ++r) {
        EXPECT_NEAR(A(3 * static_cast<int>(e) + r, k), qd(r) * st_inv[k], 1e-9 * (1.0 + std::fabs(qd(r))))
            << "column " << k << " end " << e;
      }
    }
  }
}
