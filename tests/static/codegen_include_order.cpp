// Compile-only: a model whose custom regressor calls `nlid::max` / `nlid::min` is defined
// before nlid/codegen.hpp is included (a project's own model header, then the code generator).
// The qualified calls only see the overloads declared before the lambda; the generic ones of
// ad/dual.hpp reach the TraceScalar overloads at instantiation. Building this file is the test.
#include "nlid/models/nlarx.hpp"
#include "nlid/nonlinearities/linear.hpp"
#include "nlid/regressors.hpp"
#include "nlid/regressors/expression.hpp"

namespace include_order {

inline auto spring_model() {
  auto spring = nlid::custom_regressor<nlid::OutputLag<1>>(
      "max(y1(t-1),90)+min(y1(t-1),15)-105", [](auto y) { return nlid::max(y, 90.0) + nlid::min(y, 15.0) - 105.0; });
  return nlid::Nlarx(nlid::RegressorSet{nlid::LaggedRegressors<2, 1, 0>{}, spring}, nlid::LinearMap<4>{});
}

// Regressors chosen at run time whose text calls min and max (Expression::run instantiated on
// the tracer's scalar only after the code generator's overloads exist).
inline auto expression_model() {
  nlid::RegressorList r;
  r.add_output_lags(1);
  r.add_custom("max(u1(t),0.5)+min(y1(t-1),1)", {"u1"}, "y1");
  return nlid::Nlarx<nlid::RegressorList, nlid::LinearMap<nlid::Dynamic>>(std::move(r), nlid::LinearMap<nlid::Dynamic>(2),
                                                                          0.01);
}

}  // namespace include_order

#include "nlid/codegen.hpp"

namespace include_order {

inline std::string generated() { return nlid::generate_c(spring_model(), nlid::CodegenOptions{}).source; }
[[maybe_unused]] const auto instantiate = &generated;
inline std::string generated_expression() {
  return nlid::generate_c(expression_model(), nlid::CodegenOptions{}).source;
}
[[maybe_unused]] const auto instantiate_expression = &generated_expression;

}  // namespace include_order
