#pragma once
/// Twin-Pantograph pen: the measured mass matrix (seeds/004 eq 28–29) and the pose-coordinate Jacobians of the
/// pen ends. Header-only, freestanding, templated on the scalar type (see kinematics.h for frames).
///
/// Pose coordinates x = (c_x, c_y, c_z, θx, θz): the pen centre and the two actuated rotations (Table X axes).
#include <array>
#include <cmath>

#include "phalanx/pen/kinematics.h"

namespace phalanx::pen {

template <class T>
using Mat5 = std::array<std::array<T, 5>, 5>;
/// 3×5: rows (x, y, z) of a pen end, columns the pose coordinates.
template <class T>
using Mat35 = std::array<std::array<T, 5>, 3>;

/// eq 29 as printed: units N, cm/s², N·cm, rad/s², and a common factor 1e-5. Rows (x, y, z, rot x, rot z).
inline constexpr std::array<std::array<double, 5>, 5> kMassMatrixEq29{{{190, 0.197, -0.179, 0.333, 1.52},
                                                                        {0.197, 226, -0.035, -346, -0.515},
                                                                        {-0.179, -0.035, 156, -0.642, -0.335},
                                                                        {0.333, -346, -0.642, 10300, 12},
                                                                        {1.52, -0.515, -0.335, 12, 12600}}};

/// eq 29 in SI for the pose coordinates: translational block × 1e-5 · 100 (N per cm/s² → kg), cross terms × 1e-5
/// (N per rad/s² and N·cm per cm/s² are both N·s² = kg·m), rotational block × 1e-5 · 1e-2 (N·cm·s² → kg·m²).
template <class T>
inline Mat5<T> massMatrixSI(const std::array<std::array<double, 5>, 5>& D_paper = kMassMatrixEq29) {
  Mat5<T> D{};
  for (std::size_t i = 0; i < 5; ++i) {
    for (std::size_t j = 0; j < 5; ++j) {
      const double s = (i < 3 && j < 3) ? 1e-3 : ((i >= 3 && j >= 3) ? 1e-7 : 1e-5);
      D[i][j] = static_cast<T>(D_paper[i][j] * s);
    }
  }
  return D;
}

/// Inverse of a symmetric positive-definite 5×5 (Gauss–Jordan without pivoting). False if a pivot is ≤ 0.
template <class T>
inline bool invertSpd5(Mat5<T> a, Mat5<T>& inv) {
  for (std::size_t i = 0; i < 5; ++i)
    for (std::size_t j = 0; j < 5; ++j) inv[i][j] = i == j ? T(1) : T(0);
  for (std::size_t c = 0; c < 5; ++c) {
    const T p = a[c][c];
    if (!(p > T(0))) return false;
    for (std::size_t j = 0; j < 5; ++j) {
      a[c][j] /= p;
      inv[c][j] /= p;
    }
    for (std::size_t r = 0; r < 5; ++r) {
      if (r == c) continue;
      const T f = a[r][c];
      for (std::size_t j = 0; j < 5; ++j) {
        a[r][j] -= f * a[c][j];
        inv[r][j] -= f * inv[c][j];
      }
    }
  }
  return true;
}

/// ∂p_end/∂x for end p = c + endOffset(p, l6)·a (kBottom: c − l6·a, kTop: c + l6·a) at angles (θx, θz).
template <class T>
inline Mat35<T> endJacobian(const Model<T>& model, std::size_t end, T theta_x_rad, T theta_z_rad) {
  const T sx = std::sin(theta_x_rad), cx = std::cos(theta_x_rad);
  const T sz = std::sin(theta_z_rad), cz = std::cos(theta_z_rad);
  const Vec3<T> da_dx{sz * sx, -cz * sx, cx};
  const Vec3<T> da_dz{-cz * cx, -sz * cx, T(0)};
  const T h = endOffset(end, model.l6_m);
  Mat35<T> G{};
  for (std::size_t i = 0; i < 3; ++i) {
    G[i][i] = T(1);
    G[i][3] = h * da_dx[i];
    G[i][4] = h * da_dz[i];
  }
  return G;
}

}  // namespace phalanx::pen
