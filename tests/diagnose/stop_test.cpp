// Why a diagnosis ended, and what its explanation says about it: the search's stop (SearchStop)
// decides the closing sentence, so a limit set by the user is never reported as "nothing in the
// catalogue explains it".
#include <catch2/catch.hpp>

#include <string>

#include "nlid/diagnose.hpp"
#include "nlid/diagnose/report.hpp"
#include "nlid/models/physics/catalogue.hpp"
#include "synth.hpp"
#include "../support/decimal_comma_locale.hpp"

using namespace nlid;

namespace {

// Mass-spring-damper records with Coulomb friction and a dead time (the suite's two-effect case).
Diagnosis<physics::MassSpringDamper> diagnose_two_effects(int max_effects) {
  const double ts = 0.01;
  const physics::MassSpringDamper msd;
  const DataScales s = diag_test::unit_scales(ts / 4);
  AugmentedModel<physics::MassSpringDamper> truth(
      msd, diag_test::table(msd, {{"c", 8.0}, {"k", 100.0}, {"b", 100.0}, {"rest", 0.1}}), ts / 4);
  truth.add_effect(diag_test::effect(EffectKind::coulomb_friction, {5.0}, s));
  truth.add_effect(diag_test::effect(EffectKind::dead_time, {0.03}, s));
  const Eigen::VectorXd x0 = Eigen::Vector2d(0.1, 0.0);
  Dataset est, val;
  est.add(diag_test::synthesize(truth, diag_test::random_steps(1500, -1, 1, 40, 150, 11u), ts, x0, 0.01, 21u, "est", 4));
  val.add(diag_test::synthesize(truth, diag_test::random_steps(1500, -1, 1, 40, 150, 12u), ts, x0, 0.01, 22u, "val", 4));
  DiagnoseOptions o;
  o.starts = 3;
  o.start_candidates = 8;
  o.threads = 2;
  o.max_effects = max_effects;
  return diagnose(GreyBox<physics::MassSpringDamper>(), est, val, o);
}

}  // namespace

TEST_CASE("diagnosis stopped by max_effects = 0 says no effect was tried", "[diagnose][explain]") {
  const auto d = diagnose_two_effects(0);
  INFO(d.explanation);
  CHECK(d.effects.empty());
  CHECK(d.stop == SearchStop::effect_limit);
  CHECK_FALSE(d.floor_after.consistent);  // something is missing, the search was not allowed to look
  CHECK_THAT(d.explanation, Catch::Contains("No catalogue effect was tried (max_effects = 0)"));
  CHECK_THAT(d.explanation, !Catch::Contains("None of the catalogue effects explains"));
  CHECK(diagnosis_json(d).at("stop").as_string() == "effect_limit");
}

TEST_CASE("diagnosis stopped at its effect limit says more may be missing", "[diagnose][explain]") {
  const auto d = diagnose_two_effects(1);
  INFO(d.explanation);
  REQUIRE(d.effects.size() == 1u);
  CHECK(d.stop == SearchStop::effect_limit);
  CHECK_FALSE(d.floor_after.consistent);
  CHECK_THAT(d.explanation, Catch::Contains("stopped at its limit of 1 effect(s) (max_effects), so more may be missing"));
  CHECK_THAT(d.explanation, !Catch::Contains("No further catalogue effect improved"));
}

TEST_CASE("diagnosis summary, explanation, model description and HTML report read the same under a decimal-comma locale",
          "[diagnose][explain][locale]") {
  const auto d = diagnose_two_effects(1);
  REQUIRE(d.effects.size() == 1u);
  const std::string summary = diagnosis_summary(d), why = explain(d), model = d.model.describe(),
                    html = diagnosis_report(d).str();
  REQUIRE(summary.find("validation fit ") != std::string::npos);
  const nlid_test::DecimalCommaLocale comma;
  if (nlid_test::DecimalCommaLocale::required()) REQUIRE(comma.active());
  if (!comma.active()) {
    WARN("no locale with decimal commas installed: not checked");
    return;
  }
  CHECK(diagnosis_summary(d) == summary);
  CHECK(explain(d) == why);
  CHECK(d.model.describe() == model);
  CHECK(diagnosis_report(d).str() == html);
}
