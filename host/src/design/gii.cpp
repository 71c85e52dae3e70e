#include "phalanx/host/design/gii.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <thread>

namespace phalanx::host::design {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;
}  // namespace

// -------------------------------------------------------------------------------------------------------------
// Eq 14–16
// -------------------------------------------------------------------------------------------------------------

namespace {
/// Samples on ring n (eq 14): floor(2π / Δθ2,n) with Δθ2,n = Δθ1 / sin(nΔθ1), written exactly as eq 16.
std::size_t ringCount(double tip_max_rad, std::size_t rings, std::size_t n) {
  const double N = static_cast<double>(rings);
  return static_cast<std::size_t>(
      std::floor(2.0 * kPi * N / tip_max_rad * std::sin(static_cast<double>(n) * tip_max_rad / N)));
}
}  // namespace

std::size_t axisAngleSampleCount(double tip_max_rad, std::size_t rings) {
  if (rings == 0 || !(tip_max_rad > 0)) return 1;
  std::size_t k = 1;
  for (std::size_t n = 1; n <= rings; ++n) k += ringCount(tip_max_rad, rings, n);
  return k;
}

std::vector<TiltSample> axisAngleSamples(double tip_max_rad, std::size_t rings) {
  std::vector<TiltSample> s;
  s.push_back({0.0, 0.0});
  if (rings == 0 || !(tip_max_rad > 0)) return s;
  const double dtheta1 = tip_max_rad / static_cast<double>(rings);
  for (std::size_t n = 1; n <= rings; ++n) {
    const std::size_t m = ringCount(tip_max_rad, rings, n);
    for (std::size_t k = 0; k < m; ++k) {
      s.push_back({static_cast<double>(n) * dtheta1, 2.0 * kPi * static_cast<double>(k) / static_cast<double>(m)});
    }
  }
  return s;
}

std::size_t ringsForTranslationalSamples(double tip_max_rad, double k_t, double d_r, double d_t) {
  const double k_r = std::pow(k_t, d_r / d_t);  // eq 15
  std::size_t best = 1;
  double best_err = kInf;
  for (std::size_t N = 1; N < 1000; ++N) {
    const double K = static_cast<double>(axisAngleSampleCount(tip_max_rad, N));
    const double err = std::fabs(K - k_r);
    if (err < best_err) best_err = err, best = N;
    if (K > 2 * k_r + 10) break;
  }
  return best;
}

// -------------------------------------------------------------------------------------------------------------
// Isotropy
// -------------------------------------------------------------------------------------------------------------

SigmaPair sigmaBounds(const Eigen::MatrixXd& M) {
  if (M.size() == 0) return {};
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(M);
  const Eigen::VectorXd s = svd.singularValues();
  return {s.minCoeff(), s.maxCoeff()};
}

SigmaPair sigmaBoundsFromGram(const Eigen::Matrix<double, 5, 5>& G) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 5, 5>> es(G, Eigen::EigenvaluesOnly);
  const auto& ev = es.eigenvalues();  // ascending
  return {std::sqrt(std::max(0.0, ev[0])), std::sqrt(std::max(0.0, ev[4]))};
}

double giiFromSigmas(const std::vector<SigmaPair>& s) {
  if (s.empty()) return 0;
  double lo = kInf, hi = 0;
  for (const SigmaPair& p : s) lo = std::min(lo, p.min), hi = std::max(hi, p.max);
  return hi > 0 ? lo / hi : 0.0;
}

double gii(const std::function<Eigen::MatrixXd(std::size_t)>& jacobian, std::size_t samples,
           const Eigen::VectorXd& S_J, const Eigen::VectorXd& S_T) {
  std::vector<SigmaPair> s;
  s.reserve(samples);
  for (std::size_t i = 0; i < samples; ++i) {
    const Eigen::MatrixXd J = jacobian(i);
    s.push_back(sigmaBounds(S_J.asDiagonal() * J * S_T.cwiseInverse().asDiagonal()));
  }
  return giiFromSigmas(s);
}

// -------------------------------------------------------------------------------------------------------------
// Threads
// -------------------------------------------------------------------------------------------------------------

void parallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t, std::size_t)>& fn) {
  const std::size_t t = std::max<std::size_t>(1, std::min<std::size_t>(threads, n));
  if (t <= 1) {
    if (n > 0) fn(0, n);
    return;
  }
  std::vector<std::thread> pool;
  for (std::size_t i = 0; i < t; ++i) {
    const std::size_t b = n * i / t, e = n * (i + 1) / t;
    pool.emplace_back([&fn, b, e] { fn(b, e); });
  }
  for (auto& th : pool) th.join();
}

namespace {
/// Upper bound of eq 11 from the samples seen so far (exact GII once every sample was seen).
inline double upperBound(double lo, double hi) {
  if (lo == kInf) return kInf;
  if (!(lo > 0)) return 0.0;
  return lo / hi;
}

/// a beats b: larger value, ties → smaller id.
inline bool beats(double va, std::size_t ia, double vb, std::size_t ib) {
  return va > vb || (va == vb && ia < ib);
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// What the search threads publish for the progress reports (relaxed atomics: a report is a snapshot, never an
/// input of the search).
struct LiveState {
  std::atomic<std::uint64_t> jacobians{0};
  std::atomic<std::uint64_t> pass_done{0}, pass_total{0};
  std::atomic<int> pass{0};  // index into kPassNames
  std::atomic<std::size_t> round{0}, alive{0};
  std::atomic<double> best{-1.0};
  std::atomic<double> pass_start_s{0.0};
};
constexpr const char* kPassNames[] = {"", "all alive at a sample", "leader over every sample"};

/// Calls opt.progress every opt.progress_s from its own thread until destroyed (so a report comes inside a long
/// pass, not only between rounds).
class ProgressMonitor {
 public:
  ProgressMonitor(const SearchOptions& opt, const char* search, std::size_t candidates, const LiveState& live,
                  std::chrono::steady_clock::time_point t0) {
    if (!(opt.progress_s > 0) || !opt.progress) return;
    thread_ = std::thread([this, &opt, &live, search, candidates, t0] {
      std::unique_lock<std::mutex> lock(mutex_);
      const auto period = std::chrono::duration<double>(opt.progress_s);
      while (!cv_.wait_for(lock, period, [this] { return done_; })) {
        SearchProgress p;
        p.search = search;
        p.elapsed_s = secondsSince(t0);
        p.pass_elapsed_s = p.elapsed_s - live.pass_start_s.load(std::memory_order_relaxed);
        const double total = static_cast<double>(live.pass_total.load(std::memory_order_relaxed));
        if (total > 0) p.fraction = static_cast<double>(live.pass_done.load(std::memory_order_relaxed)) / total;
        p.pass = kPassNames[live.pass.load(std::memory_order_relaxed)];
        p.round = live.round.load(std::memory_order_relaxed);
        p.alive = live.alive.load(std::memory_order_relaxed);
        p.candidates = candidates;
        p.best_gii = live.best.load(std::memory_order_relaxed);
        p.jacobian_evals = live.jacobians.load(std::memory_order_relaxed);
        opt.progress(p);
      }
    });
  }
  ~ProgressMonitor() {
    if (!thread_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  ProgressMonitor(const ProgressMonitor&) = delete;
  ProgressMonitor& operator=(const ProgressMonitor&) = delete;

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};
}  // namespace

// -------------------------------------------------------------------------------------------------------------
// Exhaustive search
// -------------------------------------------------------------------------------------------------------------

SearchResult exhaustiveSearch(const MinimaxProblem& pb, const SearchOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t G = pb.numGroups(), M = pb.groupSize(), S = pb.numSamples();
  struct Local {
    double best = -1;
    std::size_t best_id = 0;
    std::uint64_t j = 0, s = 0;
  };
  const unsigned T = std::max(1u, opt.threads);
  std::vector<Local> locals(T);
  std::atomic<unsigned> slot{0};
  LiveState live;
  live.pass_total = static_cast<std::uint64_t>(G) * S;
  live.alive = pb.numCandidates();
  ProgressMonitor monitor(opt, "exhaustive", pb.numCandidates(), live, t0);
  parallelFor(G, T, [&](std::size_t gb, std::size_t ge) {
    Local& L = locals[slot.fetch_add(1)];
    std::vector<std::uint32_t> members(M);
    for (std::size_t m = 0; m < M; ++m) members[m] = static_cast<std::uint32_t>(m);
    std::vector<SigmaPair> out(M);
    std::vector<double> lo(M), hi(M);
    for (std::size_t g = gb; g < ge; ++g) {
      std::fill(lo.begin(), lo.end(), kInf);
      std::fill(hi.begin(), hi.end(), 0.0);
      for (std::size_t s = 0; s < S; ++s) {
        pb.evaluate(g, s, members.data(), M, out.data());
        ++L.j;
        L.s += M;
        for (std::size_t m = 0; m < M; ++m) {
          lo[m] = std::min(lo[m], out[m].min);
          hi[m] = std::max(hi[m], out[m].max);
        }
      }
      live.pass_done.fetch_add(S, std::memory_order_relaxed);
      live.jacobians.fetch_add(S, std::memory_order_relaxed);
      for (std::size_t m = 0; m < M; ++m) {
        const double v = upperBound(lo[m], hi[m]);
        const std::size_t id = g * M + m;
        if (beats(v, id, L.best, L.best_id)) L.best = v, L.best_id = id;
      }
    }
  });
  SearchResult r;
  double best = -1;
  for (const Local& L : locals) {
    if (L.best >= 0 && beats(L.best, L.best_id, best, r.best)) best = L.best, r.best = L.best_id;
    r.jacobian_evals += L.j;
    r.sigma_evals += L.s;
  }
  r.gii = std::max(0.0, best);
  r.seconds = secondsSince(t0);
  return r;
}

// -------------------------------------------------------------------------------------------------------------
// Culling
// -------------------------------------------------------------------------------------------------------------

SearchResult cullingSearch(const MinimaxProblem& pb, const SearchOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t M = pb.groupSize(), S = pb.numSamples(), C = pb.numCandidates();
  const unsigned T = std::max(1u, opt.threads);
  SearchResult r;
  std::vector<double> lo(C, kInf), hi(C, 0.0);
  std::vector<std::uint8_t> done(C, 0);
  std::vector<std::uint8_t> used(S, 0);
  std::vector<std::uint32_t> alive(C);
  for (std::size_t c = 0; c < C; ++c) alive[c] = static_cast<std::uint32_t>(c);
  double best = -1;
  std::size_t best_id = 0;
  std::atomic<std::uint64_t> jev{0}, sev{0};
  LiveState live;
  live.alive = C;
  ProgressMonitor monitor(opt, "culling", C, live, t0);

  // Evaluates every alive candidate at sample s (groups split between threads at group boundaries).
  auto evaluateAlive = [&](std::size_t s) {
    const std::size_t n = alive.size();
    live.pass_done = 0;
    live.pass_total = n;
    live.pass = 1;
    live.pass_start_s = secondsSince(t0);
    std::vector<std::size_t> cuts{0};
    for (unsigned t = 1; t < T; ++t) {
      std::size_t k = n * t / T;
      while (k > 0 && k < n && alive[k] / M == alive[k - 1] / M) ++k;
      cuts.push_back(std::max(cuts.back(), std::min(k, n)));
    }
    cuts.push_back(n);
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < T; ++t) {
      pool.emplace_back([&, t] {
        std::vector<std::uint32_t> members;
        std::vector<SigmaPair> out;
        std::uint64_t j = 0, sg = 0;
        std::size_t i = cuts[t];
        while (i < cuts[t + 1]) {
          const std::size_t g = alive[i] / M;
          members.clear();
          std::size_t k = i;
          while (k < cuts[t + 1] && alive[k] / M == g) members.push_back(static_cast<std::uint32_t>(alive[k] - g * M)), ++k;
          out.resize(members.size());
          pb.evaluate(g, s, members.data(), members.size(), out.data());
          ++j;
          sg += members.size();
          live.pass_done.fetch_add(members.size(), std::memory_order_relaxed);
          live.jacobians.fetch_add(1, std::memory_order_relaxed);
          for (std::size_t q = 0; q < members.size(); ++q) {
            const std::size_t c = alive[i + q];
            lo[c] = std::min(lo[c], out[q].min);
            hi[c] = std::max(hi[c], out[q].max);
          }
          i = k;
        }
        jev += j;
        sev += sg;
      });
    }
    for (auto& th : pool) th.join();
    used[s] = 1;
    ++r.critical_samples;
  };

  auto cull = [&] {
    std::size_t w = 0;
    for (std::size_t i = 0; i < alive.size(); ++i) {
      const std::size_t c = alive[i];
      if (done[c]) continue;
      const double ub = upperBound(lo[c], hi[c]);
      if (ub < best || (ub == best && c > best_id)) continue;
      alive[w++] = alive[i];
    }
    alive.resize(w);
    live.alive = w;
  };

  evaluateAlive(std::min(pb.seedSample(), S - 1));
  for (;;) {
    cull();
    if (alive.empty()) break;
    // Leader: highest UB, ties → smallest id (alive is sorted).
    std::size_t leader = alive.front();
    double lub = upperBound(lo[leader], hi[leader]);
    for (std::uint32_t c : alive) {
      const double ub = upperBound(lo[c], hi[c]);
      if (ub > lub) lub = ub, leader = c;
    }
    ++r.rounds;
    live.round = r.rounds;
    live.pass_done = 0;
    live.pass_total = S;
    live.pass = 2;
    live.pass_start_s = secondsSince(t0);
    // Full evaluation of the leader, early stop when it cannot beat `best`.
    struct Part {
      double lo = kInf, hi = 0;
      std::size_t arg_lo = 0, arg_hi = 0;
      std::uint64_t n = 0;
    };
    std::vector<Part> parts(T);
    std::atomic<bool> stop{false};
    const std::size_t g = leader / M;
    const std::uint32_t member = static_cast<std::uint32_t>(leader - g * M);
    const double lo0 = lo[leader], hi0 = hi[leader];
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < T; ++t) {
      pool.emplace_back([&, t] {
        Part& P = parts[t];
        const std::size_t b = S * t / T, e = S * (t + 1) / T;
        SigmaPair sp;
        for (std::size_t s = b; s < e; ++s) {
          if (((s - b) & 63) == 0) {  // blocks of 64 from this thread's start: [b, e) counted exactly once
            if (stop.load(std::memory_order_relaxed)) break;
            const std::uint64_t block = std::min<std::size_t>(64, e - s);  // the last block may be shorter
            live.pass_done.fetch_add(block, std::memory_order_relaxed);
            live.jacobians.fetch_add(block, std::memory_order_relaxed);
          }
          pb.evaluate(g, s, &member, 1, &sp);
          ++P.n;
          if (sp.min < P.lo) P.lo = sp.min, P.arg_lo = s;
          if (sp.max > P.hi) P.hi = sp.max, P.arg_hi = s;
          const double ub = upperBound(std::min(lo0, P.lo), std::max(hi0, P.hi));
          if (ub < best || (ub == best && leader > best_id)) {
            stop = true;
            break;
          }
        }
      });
    }
    for (auto& th : pool) th.join();
    Part all;
    std::uint64_t n_eval = 0;
    for (const Part& P : parts) {
      n_eval += P.n;
      if (P.lo < all.lo) all.lo = P.lo, all.arg_lo = P.arg_lo;
      if (P.hi > all.hi) all.hi = P.hi, all.arg_hi = P.arg_hi;
    }
    jev += n_eval;
    sev += n_eval;
    lo[leader] = std::min(lo[leader], all.lo);
    hi[leader] = std::max(hi[leader], all.hi);
    if (!stop) {
      done[leader] = 1;
      const double v = upperBound(lo[leader], hi[leader]);  // exact GII: every sample seen
      if (beats(v, leader, best, best_id)) best = v, best_id = leader;
      live.best = best;
    }
    // The leader's critical samples become culling samples for everyone still alive.
    cull();
    if (all.lo < kInf && !used[all.arg_lo]) evaluateAlive(all.arg_lo);
    if (all.hi > 0 && !used[all.arg_hi]) evaluateAlive(all.arg_hi);
  }
  r.best = best_id;
  r.gii = std::max(0.0, best);
  r.jacobian_evals = jev;
  r.sigma_evals = sev;
  r.seconds = secondsSince(t0);
  return r;
}

}  // namespace phalanx::host::design
