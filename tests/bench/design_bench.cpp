// Design tools: culling vs exhaustive minimax search on the same discretised Twin-Pantograph problem (004 §IV),
// the cost of one Jacobian evaluation, and (opt-in, minutes) the full Table VII search.
//
//   build/host/bin/design_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
//   PHALANX_BENCH_TABLE7=1 build/host/bin/design_bench --benchmark_filter=TableVII
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <vector>

#include "phalanx/host/design/gii.h"
#include "phalanx/host/design/pen_gii.h"

namespace d = phalanx::host::design;

namespace {
/// A problem small enough for exhaustive search (seconds): 540 geometries × 6 Q1 around Table VII, a 5×3×3
/// position grid × 34 orientations (N = 3) over Table VI's workspace at 25 cm.
d::PenGiiSpec comparisonSpec() {
  d::PenGiiSpec s;
  s.l1 = {2.4, 7.0, 1.0};
  s.l2 = {10.0, 30.0, 4.0};
  s.l3 = {15.0, 35.0, 4.0};
  s.l6 = {7.0, 11.0, 2.0};
  s.q1 = {0.5, 3.0, 0.5};
  s.wi = {0.0, 8.0, 2.0};
  s.wj = {0.0, 5.0, 2.5};
  s.wk = {-5.0, 5.0, 5.0};
  s.rings = 3;
  return s;
}

const d::TwinPantographGii& comparisonProblem() {
  static const d::TwinPantographGii pb(comparisonSpec());
  return pb;
}

const d::SearchResult& exhaustiveReference() {
  static const d::SearchResult r = d::exhaustiveSearch(comparisonProblem());
  return r;
}

void BM_ExhaustiveSearch(benchmark::State& state) {
  const d::TwinPantographGii& pb = comparisonProblem();
  d::SearchResult r;
  for (auto _ : state) {
    r = d::exhaustiveSearch(pb);
    benchmark::DoNotOptimize(r.best);  // not the double: libbenchmark 1.7.1 DoNotOptimize(double&) clobbers it with GCC
  }
  state.counters["candidates"] = static_cast<double>(pb.numCandidates());
  state.counters["samples"] = static_cast<double>(pb.numSamples());
  state.counters["jacobian_evals"] = static_cast<double>(r.jacobian_evals);
  state.counters["gii"] = r.gii;
}
BENCHMARK(BM_ExhaustiveSearch)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

void BM_CullingSearch(benchmark::State& state) {
  const d::TwinPantographGii& pb = comparisonProblem();
  const d::SearchResult& ex = exhaustiveReference();
  d::SearchResult r;
  for (auto _ : state) {
    r = d::cullingSearch(pb);
    benchmark::DoNotOptimize(r.best);  // not the double: libbenchmark 1.7.1 DoNotOptimize(double&) clobbers it with GCC
  }
  state.counters["jacobian_evals"] = static_cast<double>(r.jacobian_evals);
  state.counters["gii"] = r.gii;
  state.counters["identical_optimum"] = (r.best == ex.best && r.gii == ex.gii) ? 1.0 : 0.0;
  state.counters["jacobian_ratio"] = static_cast<double>(ex.jacobian_evals) / static_cast<double>(r.jacobian_evals);
  state.counters["time_ratio_vs_exhaustive_run"] = ex.seconds / r.seconds;
}
BENCHMARK(BM_CullingSearch)->Unit(benchmark::kMillisecond)->UseRealTime();

/// One evaluate(): two pantograph IK/FK, the 6×5 Jacobian, and σ bounds for `members` Q1 values.
void BM_PenJacobianEvaluation(benchmark::State& state) {
  const d::TwinPantographGii& pb = comparisonProblem();
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  std::vector<std::uint32_t> members(n);
  for (std::size_t i = 0; i < n; ++i) members[i] = static_cast<std::uint32_t>(i % pb.groupSize());
  std::vector<d::SigmaPair> out(n);
  std::size_t s = 0;
  const std::size_t group = 100;
  for (auto _ : state) {
    pb.evaluate(group, s, members.data(), n, out.data());
    benchmark::DoNotOptimize(out.data());
    s = (s + 1) % pb.numSamples();
  }
}
BENCHMARK(BM_PenJacobianEvaluation)->Arg(1)->Arg(6);

/// Table VII: 22,027,824 candidates × 2,422,959 workspace samples, culling on 2 threads (opt-in).
void BM_TableVIISearch(benchmark::State& state) {
  const d::PenGiiSpec spec;  // defaults = Tables VI and VII, 25 cm
  const d::TwinPantographGii pb(spec);
  d::SearchResult r;
  for (auto _ : state) {
    r = d::cullingSearch(pb);
    benchmark::DoNotOptimize(r.best);  // not the double: libbenchmark 1.7.1 DoNotOptimize(double&) clobbers it with GCC
  }
  const d::PenDesign o = pb.design(r.best);
  state.counters["gii"] = r.gii;
  state.counters["l1_cm"] = o.l1;
  state.counters["l2_cm"] = o.l2;
  state.counters["l3_cm"] = o.l3;
  state.counters["l6_cm"] = o.l6;
  state.counters["Q1"] = o.q1;
  state.counters["jacobian_evals"] = static_cast<double>(r.jacobian_evals);
}

struct RegisterTableVII {
  RegisterTableVII() {
    if (std::getenv("PHALANX_BENCH_TABLE7") != nullptr) {
      benchmark::RegisterBenchmark("BM_TableVIISearch", BM_TableVIISearch)
          ->Unit(benchmark::kSecond)
          ->Iterations(1)
          ->UseRealTime();
    }
  }
} register_table_vii;
}  // namespace
