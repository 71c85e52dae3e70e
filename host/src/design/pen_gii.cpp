#include "phalanx/host/design/pen_gii.h"

#include <cmath>
#include <stdexcept>

#include "phalanx/pen/kinematics.h"

namespace phalanx::host::design {

namespace {
constexpr double kPi = 3.14159265358979323846;

/// Rodrigues rotation about the unit axis h by angle t.
Eigen::Matrix3d rotation(const Eigen::Vector3d& h, double t) { return Eigen::AngleAxisd(t, h).toRotationMatrix(); }
}  // namespace

std::size_t GridRange::count() const {
  if (!(step > 0) || max < min) return 0;
  return static_cast<std::size_t>(std::floor((max - min) / step + 1e-6)) + 1;
}

TwinPantographGii::TwinPantographGii(const PenGiiSpec& spec) : spec_(spec) {
  n_ = {spec.l1.count(), spec.l2.count(), spec.l3.count(), spec.l6.count()};
  nq_ = spec.q1.count();
  groups_ = n_[0] * n_[1] * n_[2] * n_[3];
  if (groups_ == 0 || nq_ == 0) throw std::invalid_argument("empty parameter range");
  if (static_cast<double>(groups_) * static_cast<double>(nq_) > 4.0e9) throw std::invalid_argument("more than 4e9 candidates");
  const std::size_t ni = spec.wi.count(), nj = spec.wj.count(), nk = spec.wk.count();
  if (ni * nj * nk == 0) throw std::invalid_argument("empty workspace range");
  std::size_t seed_pos = 0;
  double seed_d2 = 1e300;
  for (std::size_t a = 0; a < ni; ++a)
    for (std::size_t b = 0; b < nj; ++b)
      for (std::size_t c = 0; c < nk; ++c) {
        const double x = spec.wi.value(a), y = spec.wj.value(b), z = spec.wk.value(c);
        const double d2 = x * x + y * y + z * z;
        if (d2 < seed_d2) seed_d2 = d2, seed_pos = positions_.size();
        positions_.push_back({x, y, spec.distance_cm + z});
      }
  const double tilt = spec.tilt_max_deg * kPi / 180.0;
  rings_ = spec.rings;
  if (rings_ == 0) {
    // Eq 15 on the full translational grid (the quarter of Table VI mirrored about i = 0 and j = 0).
    auto full = [](const GridRange& r) {
      return static_cast<double>(r.min == 0.0 ? 2 * r.count() - 1 : r.count());
    };
    rings_ = ringsForTranslationalSamples(tilt, full(spec.wi) * full(spec.wj) * full(spec.wk), 2.0, 3.0);
  }
  for (const TiltSample& t : axisAngleSamples(tilt, rings_)) {
    // Tilt axis horizontal (in the ik plane) at azimuth θ2; the pen axis j tilts by θ1 (axis-angle, no roll).
    const Eigen::Vector3d h(std::cos(t.azimuth_rad), 0.0, std::sin(t.azimuth_rad));
    tilts_.push_back(t.tip_rad == 0.0 ? Eigen::Matrix3d::Identity() : rotation(h, t.tip_rad));
  }
  seed_ = seed_pos * tilts_.size();
  // S_T (eq 19 without M_j; eq 27).
  if (spec.mode == PenGiiMode::kForce) {
    st_inv_ << 1.0, 1.0, 1.0 / 1.5, 1.0 / 3.6, 1.0 / 3.9;
  } else {
    // Velocity (eq 23, 27): q̇ = J ẋ maps task → joint, so the task scaling enters as ẋ = v_i·S_T·x̃, i.e. the
    // matrix is S_J J S_T (docs/design-tools.md §"Table IX": the literal S_J J S_T⁻¹ gives GII ≈ 0.008).
    st_inv_ << 1.0, 1.0, 1.0, 0.06, 0.06;
    if (spec.velocity_literal_inverse) st_inv_ << 1.0, 1.0, 1.0, 1.0 / 0.06, 1.0 / 0.06;
  }
}

PenDesign TwinPantographGii::design(std::size_t candidate) const {
  const std::size_t q = candidate % nq_;
  std::size_t g = candidate / nq_;
  const std::size_t i6 = g % n_[3];
  g /= n_[3];
  const std::size_t i3 = g % n_[2];
  g /= n_[2];
  const std::size_t i2 = g % n_[1];
  const std::size_t i1 = g / n_[1];
  return {spec_.l1.value(i1), spec_.l2.value(i2), spec_.l3.value(i3), spec_.l6.value(i6), spec_.q1.value(q)};
}

bool TwinPantographGii::jacobian(double l1, double l2, double l3, double l6, std::size_t sample,
                                 Eigen::Matrix<double, 6, 5>& J) const {
  const std::size_t K = tilts_.size();
  const std::array<double, 3>& c = positions_[sample / K];
  const Eigen::Matrix3d& R = tilts_[sample % K];
  const Eigen::Vector3d a = R.col(1);  // pen axis (j of the end-effector frame)
  std::array<Eigen::Matrix3d, 2> Jinv;
  for (std::size_t p = 0; p < 2; ++p) {
    pen::PantographGeometry<double> g{};
    g.l1_m = l1;  // cm: the kinematics are scale-free
    g.l2_m = l2;
    g.l3_m = l3;
    g.y_waist_m = (p == pen::kBottom ? -0.5 : 0.5) * spec_.l4_cm;
    // The controller's reading of l6 (centre → universal joint): one definition, pen::penEnd/endOffset.
    const pen::Vec3<double> tip = pen::penEnd(p, l6, {c[0], c[1], c[2]}, {a[0], a[1], a[2]});
    pen::Vec3<double> q{};
    if (pen::pantographInverse(g, tip, q) != pen::Status::kOk) return false;
    pen::PantographData<double> d;
    if (pen::pantographForward(g, q, d) != pen::Status::kOk) return false;
    Eigen::Matrix3d Jp;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) Jp(r, k) = d.J[static_cast<std::size_t>(r)][static_cast<std::size_t>(k)];
    const double det = Jp.determinant();
    // Relative singularity test: |det| against the product of the column norms (scale-free).
    if (!(std::fabs(det) > 1e-12 * Jp.col(0).norm() * Jp.col(1).norm() * Jp.col(2).norm())) return false;
    Jinv[p] = Jp.inverse();
  }
  // Columns: unit twists in the end-effector frame (v_i, v_j, v_k, ω_i, ω_k), mapped to both tips and
  // through the inverse tip Jacobians: ṗ_end = v + ω × (endOffset(end, l6) · a).
  for (int k = 0; k < 5; ++k) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
    if (k < 3) v = R.col(k);
    else w = R.col(k == 3 ? 0 : 2);
    const Eigen::Vector3d pb = v + w.cross(pen::endOffset(pen::kBottom, l6) * a);
    const Eigen::Vector3d pt = v + w.cross(pen::endOffset(pen::kTop, l6) * a);
    J.block<3, 1>(0, k) = Jinv[0] * pb;
    J.block<3, 1>(3, k) = Jinv[1] * pt;
  }
  return true;
}

void TwinPantographGii::evaluate(std::size_t group, std::size_t sample, const std::uint32_t* members, std::size_t n,
                                 SigmaPair* out) const {
  const PenDesign d = design(group * nq_);
  Eigen::Matrix<double, 6, 5> J;
  if (!jacobian(d.l1, d.l2, d.l3, d.l6, sample, J)) {
    for (std::size_t i = 0; i < n; ++i) out[i] = {0.0, 1.0};  // unreachable/singular: GII 0
    return;
  }
  J = J * st_inv_.asDiagonal();
  // Gram matrices of the shoulder rows and of the waist rows (S_J scales the waist rows 0 and 3 by Q).
  Eigen::Matrix<double, 5, 5> Gs = Eigen::Matrix<double, 5, 5>::Zero(), Gw = Gs;
  for (int r = 0; r < 6; ++r) {
    const Eigen::Matrix<double, 1, 5> row = J.row(r);
    if (r == 0 || r == 3) Gw.noalias() += row.transpose() * row;
    else Gs.noalias() += row.transpose() * row;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double q = spec_.q1.value(members[i]);
    out[i] = sigmaBoundsFromGram(Gs + (q * q) * Gw);
  }
}

bool TwinPantographGii::scaledJacobian(const PenDesign& d, std::size_t sample, Eigen::Matrix<double, 6, 5>& out) const {
  if (!jacobian(d.l1, d.l2, d.l3, d.l6, sample, out)) return false;
  Eigen::Matrix<double, 6, 1> sj;
  sj << d.q1, 1, 1, d.q1, 1, 1;
  out = sj.asDiagonal() * out * st_inv_.asDiagonal();
  return true;
}

double penGii(const TwinPantographGii& pb, const PenDesign& d) {
  double lo = 1e300, hi = 0;
  Eigen::Matrix<double, 6, 5> A;
  for (std::size_t s = 0; s < pb.numSamples(); ++s) {
    if (!pb.scaledJacobian(d, s, A)) return 0.0;
    const SigmaPair sp = sigmaBounds(A);
    lo = std::min(lo, sp.min);
    hi = std::max(hi, sp.max);
  }
  return hi > 0 ? lo / hi : 0.0;
}

}  // namespace phalanx::host::design
