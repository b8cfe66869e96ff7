// Fuzzes model-file loading (io/model_file.hpp, `load_model(path)` → AnyModel) and then uses
// the model: a file that loads must simulate, predict, describe itself, save and reload bit for
// bit, and generate C, without a crash, a sanitizer report, a hang or a huge allocation.
//
// Contract checked here:
// - a file the reader refuses throws nlid::Error whose message names the file (and so the key
//   path, which every serialiser error carries next to it); any other exception is a defect;
// - a model that loads has finite parameters (a NaN or infinity from parsing is a defect) and
//   channel counts that agree with its names;
// - using it may throw nlid::Error (an unstable model diverges, a record shorter than the
//   model's memory is refused), but nothing else; non-finite simulation output of finite
//   parameters is allowed (an unstable model);
// - saving it and loading the copy gives the same parameters and the same simulation, bit for bit.
//
// Seeds: tests/fuzz/seeds/model_file/ (written by tests/fuzz/model_file_seeds.cpp);
// dictionary: tests/fuzz/model_file.dict.
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <new>
#include <string>
#include <typeinfo>

#include <Eigen/Core>

#include "nlid/codegen/any_model.hpp"
#include "nlid/core/error.hpp"
#include "nlid/data/experiment.hpp"
#include "nlid/io/augmented_serial.hpp"
#include "nlid/io/series_serial.hpp"
#include "nlid/models/any_model.hpp"

#include "fuzz_support.hpp"

namespace {

[[noreturn]] void model_fuzz_defect(const std::string& what) {
  std::fprintf(stderr, "model_file_fuzz: DEFECT: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

std::string model_fuzz_path(const char* tag) {
  static const std::string dir = [] {
    const char* t = std::getenv("TMPDIR");
    return std::string(t != nullptr && *t != '\0' ? t : "/tmp");
  }();
  return dir + "/nlid_model_fuzz_" + std::to_string(static_cast<long>(getpid())) + "_" + tag + ".json";
}

// Removes the per-process files when libFuzzer exits normally (a crash keeps them for a look).
struct ModelFuzzCleanup {
  std::string in, copy;
  ~ModelFuzzCleanup() {
    std::remove(in.c_str());
    std::remove(copy.c_str());
  }
};

bool model_fuzz_bits_equal(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    const double x = a.data()[i], y = b.data()[i];
    if (std::isnan(x) && std::isnan(y)) continue;
    if (std::bit_cast<std::uint64_t>(x) != std::bit_cast<std::uint64_t>(y)) return false;
  }
  return true;
}

// A grey box whose integrator may take far more steps per sample than the defaults (up to
// 10^5 fixed sub-steps or 10^6 adaptive steps, the limits of integrators.hpp): legitimate, but
// each of its simulations of 50 samples can take seconds under the sanitizers, and the estimated
// initial condition runs dozens. Such a model is run on a shorter record and from given
// initial conditions only, so that a slow but valid file is not reported as a hang.
bool model_fuzz_costly(const nlid::AnyModel& m) {
  const auto costly = [](const nlid::IntegratorOptions& o) {
    return o.method == nlid::IntegratorMethod::dormand_prince || o.substeps > 2000 || o.max_substeps > 2000;
  };
  if (const auto* g = m.target<nlid::DynamicGreyBox>()) return costly(g->integrator());
  if (const auto* a = m.target<nlid::AugmentedModel<nlid::AnyPhysics>>()) return costly(a->integrator());
  return false;
}

// A short fixed record of the model's channel counts: steps and a slow sine, outputs that follow.
nlid::Experiment model_fuzz_record(int nu, int ny, double ts, int n) {
  Eigen::MatrixXd u(n, nu), y(n, ny);
  for (int k = 0; k < n; ++k) {
    for (int c = 0; c < nu; ++c) u(k, c) = (k / 10 % 2 == 0 ? 0.5 : -0.25) + 0.1 * std::sin(0.3 * k + c);
    for (int c = 0; c < ny; ++c) y(k, c) = 0.2 * std::cos(0.2 * k + c) + 0.05 * k / n;
  }
  return nlid::Experiment(u, y, ts, "fuzz");
}

// Runs `f`; an nlid::Error is an accepted outcome, any other exception a defect.
template <class F>
bool model_fuzz_try(const char* step, F&& f) {
  return nlid_fuzz::run_step(step, "file", f, [](const std::string& what) { model_fuzz_defect(what); });
}

void model_fuzz_use(const nlid::AnyModel& m, const std::string& copy_path) {
  const int nu = m.num_inputs(), ny = m.num_outputs();
  if (nu < 0 || ny < 1) {
    model_fuzz_defect("loaded model has " + std::to_string(nu) + " inputs and " + std::to_string(ny) + " outputs");
  }
  if (static_cast<int>(m.input_names().size()) != nu || static_cast<int>(m.output_names().size()) != ny) {
    model_fuzz_defect("channel names disagree with the channel counts");
  }
  const Eigen::VectorXd theta = m.parameters();
  if (!theta.allFinite()) model_fuzz_defect("a loaded model has a non-finite parameter");
  if (m.parameter_names().size() != static_cast<std::size_t>(theta.size())) {
    model_fuzz_defect("parameter names and values differ in count");
  }
  const double ts = m.ts();
  if (!(ts >= 0) || !std::isfinite(ts)) model_fuzz_defect("a loaded model has sample time " + std::to_string(ts));
  (void)m.history_length();
  (void)m.has_predictor();
  (void)m.describe();
  // A grey box's estimated initial condition runs a Levenberg-Marquardt fit of simulations with
  // up to max_substeps RK4 steps per sample: a stiff but valid file (a throttle stop of 1e14 1/s^2)
  // takes half a second natively, many under the sanitizers. Grey boxes get a shorter record.
  const bool costly = model_fuzz_costly(m);
  const bool greybox =
      m.target<nlid::DynamicGreyBox>() != nullptr || m.target<nlid::AugmentedModel<nlid::AnyPhysics>>() != nullptr;
  const nlid::Experiment e = model_fuzz_record(nu, ny, ts > 0 ? ts : 0.01, costly ? 5 : greybox ? 10 : 50);

  Eigen::MatrixXd y0;
  const bool simulated = model_fuzz_try("simulate(zero)", [&] { y0 = m.simulate(e, nlid::InitialCondition::zero); });
  if (simulated && (y0.rows() != e.size() || y0.cols() != ny)) model_fuzz_defect("simulation has the wrong shape");
  (void)model_fuzz_try("simulate(measured)", [&] { (void)m.simulate(e, nlid::InitialCondition::measured); });
  (void)model_fuzz_try("simulate(equilibrium)", [&] { (void)m.simulate(e, nlid::InitialCondition::equilibrium); });
  if (!costly) {
    (void)model_fuzz_try("simulate(default)", [&] { (void)m.simulate(e); });
    (void)model_fuzz_try("predict(1)", [&] { (void)m.predict(e, 1); });
    (void)model_fuzz_try("predict(3)", [&] { (void)m.predict(e, 3); });
  }

  // Round trip: the copy is the same model.
  bool saved = model_fuzz_try("save", [&] { m.save(copy_path); });
  if (saved) {
    nlid::AnyModel back;
    try {
      back = nlid::load_model(copy_path);
    } catch (const nlid::Error& err) {
      model_fuzz_defect(std::string("a saved model does not load again: ") + err.what());
    }
    if (back.kind() != m.kind()) model_fuzz_defect("round trip changed the kind");
    if (!model_fuzz_bits_equal(back.parameters(), theta)) model_fuzz_defect("round trip changed the parameters");
    if (simulated) {
      Eigen::MatrixXd y1;
      try {
        y1 = back.simulate(e, nlid::InitialCondition::zero);
      } catch (const nlid::Error& err) {
        model_fuzz_defect(std::string("the reloaded model does not simulate: ") + err.what());
      }
      if (!model_fuzz_bits_equal(y0, y1)) model_fuzz_defect("round trip changed the simulation");
    }
  }

  // C code: cheap for the small models the fuzzer makes; skip large ones.
  if (theta.size() <= 400) {
    // A continuous-time model (a grey box) needs the step's sample time; a sampled one without
    // a sample time takes it too.
    nlid::CodegenOptions o;
    if (!(ts > 0)) o.ts = 0.01;
    (void)model_fuzz_try("generate_c", [&] { (void)nlid::generate_c(m, o); });
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::string path = model_fuzz_path("in");
  static const std::string copy = model_fuzz_path("copy");
  static const ModelFuzzCleanup cleanup{path, copy};
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  nlid::AnyModel m;
  try {
    m = nlid::load_model(path);
  } catch (const nlid::Error& e) {
    // The contract for a bad file: an nlid::Error that names it (in its location; the message
    // text may be cut short by a NUL byte quoted from the file).
    if (e.where().file != path && std::string(e.what()).find(path) == std::string::npos) {
      model_fuzz_defect(std::string("the error for a bad file does not name it: ") + e.what());
    }
    return 0;
  } catch (const std::bad_alloc&) {
    model_fuzz_defect("load_model: std::bad_alloc (a size from the file was not validated)");
  } catch (const std::exception& e) {
    model_fuzz_defect(std::string("load_model: ") + typeid(e).name() + ": " + e.what());
  } catch (...) {
    model_fuzz_defect("load_model: an exception of unknown type");
  }
  model_fuzz_use(m, copy);
  return 0;
}
