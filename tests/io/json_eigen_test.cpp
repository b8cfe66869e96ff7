#include "nlid/io/json_eigen.hpp"

#include <Eigen/Core>
#include <bit>
#include <catch2/catch.hpp>
#include <cstdint>
#include <limits>

TEST_CASE("Eigen vectors and matrices round trip through JSON bit-exactly") {
  Eigen::VectorXd theta(4);
  theta << 0.1, -2.5e-17, 1.0 / 3.0, 12345.0;
  Eigen::Matrix<double, 2, 3> a;
  a << 1, 2, 3, 4, 5, 6.5;
  Eigen::Matrix<double, 2, 2, Eigen::RowMajor> rm;
  rm << 1, 2, 3, 4;
  Eigen::RowVector3f rv(0.1f, 0.2f, 0.3f);

  nlid::Json j;
  j["theta"] = theta;
  j["a"] = a;
  j["rm"] = rm;
  j["rv"] = rv;
  j["expr"] = nlid::to_json(2.0 * theta.head(2));             // expressions go through to_json
  CHECK(j.at("a").json().dump(-1) == "[[1,2,3],[4,5,6.5]]");  // rows, whatever the storage
  CHECK(j.at("rm").json().dump(-1) == "[[1,2],[3,4]]");
  CHECK(j.at("expr").json().dump(-1) == "[0.2,-5e-17]");

  const nlid::Json back = nlid::Json::parse(j.dump());
  const auto t2 = back.at("theta").get<Eigen::VectorXd>();
  REQUIRE(t2.size() == 4);
  for (int i = 0; i < 4; ++i) {
    CHECK(std::bit_cast<std::uint64_t>(t2(i)) == std::bit_cast<std::uint64_t>(theta(i)));
  }
  CHECK(back.at("a").get<Eigen::MatrixXd>() == a);
  CHECK((back.at("a").get<Eigen::Matrix<double, 2, 3>>()) == a);
  CHECK((back.at("rm").get<Eigen::Matrix<double, 2, 2, Eigen::RowMajor>>()) == rm);
  CHECK(back.at("rv").get<Eigen::RowVector3f>() == rv);  // float -> double -> float is exact
  CHECK(back.at("theta").get<Eigen::ArrayXd>().matrix() == theta);
  CHECK(nlid::Json::parse("[]").get<Eigen::MatrixXd>().size() == 0);
}

TEST_CASE("Reading Eigen types checks the shape and names the key path") {
  const nlid::Json j = nlid::Json::parse(
      R"({"model": {"theta": [1, 2, 3], "m": [[1, 2], [3]], "bad": [[1, "x"]], "v": 5}})",
      "m.json");
  const auto model = j.at("model");
  CHECK_THROWS_WITH(model.at("theta").get<Eigen::Vector4d>(),
                    "nlid: expected 4 elements at model.theta, found 3 [at file 'm.json', row 1, "
                    "column 21]");
  CHECK_THROWS_WITH(
      model.at("m").get<Eigen::MatrixXd>(),
      Catch::StartsWith("nlid: ragged matrix: row model.m[1] has 1 elements, row 0 has 2"));
  CHECK_THROWS_WITH(
      model.at("bad").get<Eigen::MatrixXd>(),
      Catch::StartsWith("nlid: expected number at model.bad[0][1], found string \"x\""));
  CHECK_THROWS_WITH(model.at("v").get<Eigen::VectorXd>(),
                    Catch::StartsWith("nlid: expected array at model.v, found number 5"));
  CHECK_THROWS_WITH((model.at("m").get<Eigen::Matrix<double, 3, 2>>()),
                    Catch::StartsWith("nlid: expected 3 rows at model.m, found 2"));
  CHECK_THROWS_WITH((model.at("bad").get<Eigen::Matrix<double, 1, 3>>()),
                    Catch::StartsWith("nlid: expected 3 elements at model.bad"));
  const nlid::Json wide = nlid::Json::parse("[[1, 2, 3]]");
  CHECK_THROWS_WITH((wide.get<Eigen::Matrix<double, Eigen::Dynamic, 2>>()),
                    Catch::StartsWith("nlid: expected 2 columns at [0], found 3"));
  // Bounded dynamic sizes (MaxRows/MaxCols) are limits too: a longer array is an error, not a
  // write past the inline storage.
  using Bounded = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 2, 1>;
  CHECK_THROWS_WITH(model.at("theta").get<Bounded>(),
                    Catch::StartsWith("nlid: expected at most 2 elements at model.theta, found 3"));
  CHECK(nlid::Json::parse("[7, 8]").get<Bounded>() == Eigen::Vector2d(7, 8));
  using BoundedRow = Eigen::Matrix<double, 1, Eigen::Dynamic, Eigen::RowMajor, 1, 2>;
  CHECK_THROWS_WITH(model.at("theta").get<BoundedRow>(),
                    Catch::StartsWith("nlid: expected at most 2 elements at model.theta"));
  using BoundedMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 2, 2>;
  CHECK_THROWS_WITH(wide.get<BoundedMatrix>(),
                    Catch::StartsWith("nlid: expected at most 2 columns at [0], found 3"));
  CHECK_THROWS_WITH(nlid::Json::parse("[[1], [2], [3]]").get<BoundedMatrix>(),
                    Catch::StartsWith("nlid: expected at most 2 rows at top level, found 3"));
  // NaN in a vector is refused when written, with its index.
  Eigen::Vector2d nan_vec(1.0, std::numeric_limits<double>::quiet_NaN());
  nlid::Json k;
  k["p"] = nan_vec;
  CHECK_THROWS_WITH(k.dump(), Catch::Contains("(nan) at p[1]"));
}
