// fbar_study_cases: one run of a validation case (tests/validation/*_case.h) for the study runner
// (tools/study/run_study.py --problem bar), on either engine, printed as one JSON line.
//
// The cases whose set-up a scene file cannot express (the vibrating bar starts from the first mode's velocity field)
// run here through the same headers as the validation tests, so the study measures exactly what the tests assert.
//
// usage: fbar_study_cases --problem=bar|hydrostatic --engine=cpu|gpu --precision=single|double|mixed
//                         --problem=granular (the same schemes; --cells = H0/dx, 20 in the validation)
//                         --problem=disks (the same schemes; --cells = R/dx, 4 to 16 in the validation)
//                         --scheme=APIC|PIC-FLIP|FLIP|ASFLIP (bar, granular) --fbar=<psi> (hydrostatic)
//                         --problem=stability (the whole stability map: one JSON line per run; --scheme, --cells
//                         unused)
//                         --cells=<L/dx or H/dx>
//                         [--periods=2.6] (bar)
// (mixed: CPU engine only.) Exit code 0 with the JSON line, 1 for a failed run (the line says why), 2 for bad usage.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "../../tests/engine/gpu/gpu_validation_engine.h"
#include "../../tests/validation/granular_collapse_case.h"
#include "../../tests/validation/hydrostatic_column_case.h"
#include "../../tests/validation/stability_case.h"
#include "../../tests/validation/two_disks_case.h"
#include "../../tests/validation/vibrating_bar_case.h"
#include "MnSystem/Cuda/device_query.h"

namespace {

using namespace fbar;

std::string arg(int argc, char** argv, const char* key, const char* fallback) {
  const std::size_t n = std::strlen(key);
  for (int i = 1; i < argc; ++i)
    if (std::strncmp(argv[i], key, n) == 0 && argv[i][n] == '=') return argv[i] + n + 1;
  return fallback;
}

template <class Engine>
int bar(const validation::Scheme& scheme, double cells, double periods, const std::string& tag) {
  using namespace bar_case;
  const double dx = kL / cells;
  const auto start = std::chrono::steady_clock::now();
  const BarResult r = run_bar<Engine>(dx, periods, validation::WallFit::LastWallNodePlane, scheme);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!r.ok || r.peaks.size() < 5) {
    std::printf("{\"problem\": \"bar\", %s, \"status\": \"failed\"}\n", tag.c_str());
    return 1;
  }
  // Loss of the centre-of-mass velocity amplitude per period, from the extrema at t = 0 and two periods later.
  const double decay = 1 - std::sqrt(r.peaks[4] / r.peaks[0]);
  std::printf("{\"problem\": \"bar\", %s, \"status\": \"ok\", \"cells\": %.6g, \"dx\": %.6g, \"period\": %.9g, "
              "\"period_error\": %.6g, \"amplitude_loss_per_period\": %.6g, \"energy_max_over_e0\": %.9g, "
              "\"tip_amplitude_error\": %.6g, \"steps\": %lld, \"particles\": %zu, \"wall_s\": %.6g, "
              "\"simulated_s\": %.6g}\n",
              tag.c_str(), cells, dx, r.period, std::fabs(r.period / kPeriod - 1), decay, r.energy_max / r.energy0,
              std::fabs(r.tip_amplitude / kTipAmplitude - 1), r.steps, r.particles, wall, periods * kPeriod);
  return 0;
}

/// The hydrostatic column from rest without stress (hydrostatic_column_case.h, the cb-geo procedure) to t = 0.6 s.
template <typename T, typename TG, class Engine>
int column(double cells, double psi, const std::string& tag) {
  using namespace hydrostatic_case;
  const double dx = kH / cells;
  const double t_end = 0.6;
  const auto start = std::chrono::steady_clock::now();
  const ColumnResult r =
      run_column<T, TG, Engine>(dx, Start::StressFree, t_end, validation::WallFit::LastWallNodePlane, psi);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!r.ok) {
    std::printf("{\"problem\": \"hydrostatic\", %s, \"status\": \"failed\"}\n", tag.c_str());
    return 1;
  }
  std::printf("{\"problem\": \"hydrostatic\", %s, \"status\": \"ok\", \"cells\": %.6g, \"dx\": %.6g, "
              "\"profile_rms\": %.6g, \"base_error\": %.6g, \"checkerboard\": %.6g, \"bottom_cell_error\": %.6g, "
              "\"steps\": %lld, \"particles\": %zu, \"wall_s\": %.6g, \"simulated_s\": %.6g}\n",
              tag.c_str(), cells, dx, r.profile_rms, std::fabs(r.base_fit_error()), r.checkerboard,
              r.cell_error.empty() ? 0.0 : std::fabs(r.cell_error.front()), r.steps, r.particles, wall, t_end);
  return 0;
}

/// The granular column collapse (granular_collapse_case.h, Lube et al. 2005, a = 0.5) to rest at t = 3 s.
template <class Engine>
int granular(const validation::Scheme& scheme, double cells, const std::string& tag) {
  using namespace granular_case;
  const double dx = kGranularH0 / cells;
  const auto start = std::chrono::steady_clock::now();
  const GranularResult r = run_granular_collapse<Engine>("study", dx, scheme);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!r.ok) {
    std::printf("{\"problem\": \"granular\", %s, \"status\": \"failed\"}\n", tag.c_str());
    return 1;
  }
  // Lube et al.'s runout for a = 0.5 is 1.2 a = 0.6 (experimental band +-20 %).
  std::printf("{\"problem\": \"granular\", %s, \"status\": \"ok\", \"cells\": %.6g, \"dx\": %.6g, "
              "\"runout\": %.6g, \"runout_error_vs_lube\": %.6g, \"height_ratio\": %.6g, "
              "\"kinetic_over_released\": %.6g, \"steps\": %lld, \"particles\": %zu, \"wall_s\": %.6g, "
              "\"simulated_s\": 3}\n",
              tag.c_str(), cells, dx, r.runout, std::fabs(r.runout / 0.6 - 1), r.height_ratio, r.kinetic / r.released,
              r.steps, r.particles, wall);
  return 0;
}

/// Two elastic disks colliding (two_disks_case.h, Sulsky et al. 1994) to t = 4.5 s: the energy lost is the error
/// (the continuum impact is elastic).
template <class Engine>
int disks(const validation::Scheme& scheme, double cells, const std::string& tag) {
  using namespace disks_case;
  const double dx = kR / cells;
  const auto start = std::chrono::steady_clock::now();
  const DisksResult r = run_disks<Engine>(dx, 4.5, scheme);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!r.ok) {
    std::printf("{\"problem\": \"disks\", %s, \"status\": \"failed\"}\n", tag.c_str());
    return 1;
  }
  std::printf("{\"problem\": \"disks\", %s, \"status\": \"ok\", \"cells\": %.6g, \"dx\": %.6g, "
              "\"energy_lost\": %.6g, \"energy_max_over_e0\": %.9g, \"restitution\": %.6g, "
              "\"momentum_drift\": %.3g, \"steps\": %lld, \"particles\": %zu, \"wall_s\": %.6g, "
              "\"simulated_s\": 4.5}\n",
              tag.c_str(), cells, dx, 1 - r.energy_end / r.energy0, r.energy_max / r.energy0, -r.v_end[0][0] / kSpeed,
              r.momentum_drift, r.steps, r.particles, wall);
  return 0;
}

/// The stability maps (stability_case.h): every run of them, one JSON line each. Map "cfl": the bodies' CFL number
/// against the scheme (splash with lone particles, stiffness 10); "stiffness": c0 over the front speed against the
/// scheme (CFL 0.5); "poisson": Poisson's ratio against the scheme with F-bar off and on (block).
template <typename T, typename TG, class Engine>
int stability(const std::string& tag) {
  using namespace stability_case;
  auto print = [&](const char* map, const char* problem, const validation::Scheme& scheme, const char* x_name,
                   double x, double fbar_psi, const StabilityResult& r) {
    std::string message;
    for (char c : r.message) message += (c == '"' || c == '\\') ? '\'' : (c == '\n' ? ' ' : c);
    std::printf("{\"problem\": \"stability\", %s, \"map\": \"%s\", \"case\": \"%s\", \"scheme\": \"%s\", "
                "\"fbar\": %g, \"x_name\": \"%s\", \"x\": %g, \"state\": \"%s\", \"energy_gain\": %.4g, "
                "\"steps\": %lld, \"particles\": %zu, \"wall_s\": %.4g, \"simulated_s\": %.6g, "
                "\"message\": \"%s\", \"status\": \"ok\"}\n",
                tag.c_str(), map, problem, scheme.name, fbar_psi, x_name, x, to_string(r.state), r.energy_gain, r.steps,
                r.particles, r.seconds, r.simulated, message.c_str());
    std::fflush(stdout);
  };
  for (const validation::Scheme& scheme : validation::kTransferSchemes) {
    for (double cfl : {0.2, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0}) {
      SplashSetup s;
      s.scheme = scheme;
      s.cfl = cfl;
      print("cfl", "splash", scheme, "CFL", cfl, 0, run_splash<T, TG, Engine>(s));
    }
    for (double k : {0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0}) {
      SplashSetup s;
      s.scheme = scheme;
      s.stiffness = k;
      print("stiffness", "splash", scheme, "stiffness", k, 0, run_splash<T, TG, Engine>(s));
    }
    for (double psi : {0.0, 1.0})
      for (double nu : {0.3, 0.45, 0.49, 0.499}) {
        BlockSetup b;
        b.scheme = scheme;
        b.poisson = nu;
        b.fbar_psi = psi;
        print("poisson", "block", scheme, "poisson", nu, psi, run_block<T, TG, Engine>(b));
      }
  }
  return 0;
}

/// The engine and its scalar types for --engine and --precision, as a tag type handed to `run`.
template <typename T, typename TG, class E>
struct EngineChoice {
  using scalar = T;
  using grid_scalar = TG;
  using engine = E;
};

template <class Run>
int on_engine(const std::string& engine, const std::string& precision, Run&& run) {
  if (engine == "cpu") {
    if (precision == "single") return run(EngineChoice<float, float, CpuEngine<float>>{});
    if (precision == "double") return run(EngineChoice<double, double, CpuEngine<double>>{});
    if (precision == "mixed") return run(EngineChoice<double, float, CpuEngine<double, float>>{});
  } else if (engine == "gpu") {
    if (cuda::device_count() == 0) {
      std::fprintf(stderr, "fbar_study_cases: --engine=gpu: %s\n", cuda::no_device_reason().c_str());
      return 2;
    }
    if (precision == "single") return run(EngineChoice<float, float, test::GpuValidationEngine<float>>{});
    if (precision == "double") return run(EngineChoice<double, double, test::GpuValidationEngine<double>>{});
  }
  std::fprintf(stderr, "fbar_study_cases: --engine=%s --precision=%s: expected cpu (single, double, mixed) or gpu "
                       "(single, double)\n", engine.c_str(), precision.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string problem = arg(argc, argv, "--problem", "bar");
  const std::string engine = arg(argc, argv, "--engine", "cpu");
  const std::string precision = arg(argc, argv, "--precision", "double");
  const std::string scheme_name = arg(argc, argv, "--scheme", "APIC");
  const double cells = std::atof(arg(argc, argv, "--cells", "50").c_str());
  const double periods = std::atof(arg(argc, argv, "--periods", "2.6").c_str());
  const double psi = std::atof(arg(argc, argv, "--fbar", "0").c_str());
  // --scheme names the first word of a validation::kTransferSchemes entry (APIC, PIC-FLIP, FLIP, ASFLIP).
  const validation::Scheme* scheme = nullptr;
  for (const validation::Scheme& s : validation::kTransferSchemes)
    if (std::string(s.name).substr(0, std::string(s.name).find(' ')) == scheme_name) scheme = &s;
  if (!scheme) {
    std::fprintf(stderr, "fbar_study_cases: --scheme=%s: expected APIC, PIC-FLIP, FLIP or ASFLIP\n", scheme_name.c_str());
    return 2;
  }
  if ((problem != "bar" && problem != "hydrostatic" && problem != "granular" && problem != "disks" &&
       problem != "stability") || !(cells > 0) || !(periods >= 2.6)) {
    std::fprintf(stderr, "fbar_study_cases: expected --problem=bar, hydrostatic, granular, disks or stability, "
                         "--cells > 0 and --periods >= 2.6\n");
    return 2;
  }
  const std::string tag = "\"engine\": \"" + engine + "\", \"precision\": \"" + precision + "\", \"scheme\": \"" +
                          scheme_name + "\", \"fbar\": " + std::to_string(psi);
  return on_engine(engine, precision, [&](auto choice) {
    using C = decltype(choice);
    using E = typename C::engine;
    if (problem == "stability")
      return stability<typename C::scalar, typename C::grid_scalar, E>("\"engine\": \"" + engine +
                                                                       "\", \"precision\": \"" + precision + "\"");
    if (problem == "hydrostatic") return column<typename C::scalar, typename C::grid_scalar, E>(cells, psi, tag);
    if (problem == "granular") return granular<E>(*scheme, cells, tag);
    if (problem == "disks") return disks<E>(*scheme, cells, tag);
    return bar<E>(*scheme, cells, periods, tag);
  });
}
