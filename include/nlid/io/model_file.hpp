#pragma once
/// @file
/// Versioned model files: save an estimated model, load it back exactly (docs/model_files.md).
///
/// A model file is one JSON object:
///
///     {
///       "format": "nlid-model",          what this file is
///       "version": 1,                    layout version (see the policy below)
///       "kind": "nlarx",                 model kind (ModelSerial<M>::kind)
///       "created": "2024-05-01T12:00:00Z", "generator": "nlid", "description": "...",
///       "ts": 0.01, "inputs": [...], "outputs": [...], "initial_condition": "zero",
///       "structure": {...}, "parameters": {"names": [...], "values": [...]}, "report": {...}
///     }
///
/// Exact round trip: every double is written as the shortest decimal that reads back to the same
/// bits, so a reloaded model has the same θ and the same normalisation and simulates bit for bit
/// like the saved one (tested). Files are written atomically (temp file + rename,
/// `nlid::write_file_atomically`): a crash never leaves half a model behind.
///
/// Version policy. `version` counts incompatible layout changes. A reader accepts every version
/// up to its own (`model_file_version`) and refuses a newer file with an error saying so — never
/// by guessing. Adding an optional member does not change the version; readers reject unknown
/// members of known objects (so a typo in a hand-edited file is caught) except at the top level,
/// where members a reader does not know are ignored, so newer writers can add annotations.
///
/// Two ways to load:
/// - `load_model(path)` (models/any_model.hpp) builds the structure at run time: `AnyModel`;
/// - `load_model<M>(path)` builds a compile-time type M, and `load_model(path, prototype)` fills a
///   model built in C++ (needed when the structure holds C++ lambdas), checking that the file's
///   structure is the prototype's.
///
/// Errors name the file and the key path of what is wrong or missing (with line and column), e.g.
/// "missing key 'units' at structure.nonlinearity [at file 'm.json', row 14, column 22]".

#include <string>
#include <utility>

#include "nlid/core/atomic_file.hpp"
#include "nlid/core/error.hpp"
#include "nlid/io/json.hpp"
#include "nlid/io/model_serial.hpp"

namespace nlid {

/// The model-file layout version this reader writes and the newest it reads.
inline constexpr int model_file_version = 1;

/// The whole model file as JSON (envelope + model members).
template <SavableModel M>
[[nodiscard]] Json model_to_json(const M& model, const ModelFileInfo& info = {}) {
  Json j = Json::object();
  j["format"] = "nlid-model";
  j["version"] = model_file_version;
  j["kind"] = ModelSerial<M>::kind;
  j["created"] = info.created.empty() ? utc_timestamp() : info.created;
  j["generator"] = "nlid";
  j["description"] = info.description;
  ModelSerial<M>::save(j, model, info);
  return j;
}

/// Writes `model` to `path` atomically. Throws `nlid::Error` naming the file on failure, or
/// naming the key path of a value that cannot be written (a non-finite parameter).
template <SavableModel M>
void save_model(const std::string& path, const M& model, const ModelFileInfo& info = {}) {
  const Json j = model_to_json(model, info);
  std::string text = j.dump(2);
  text.push_back('\n');
  write_file_atomically(path, text);
}

/// Checks the envelope of a parsed model file ("format", "version", "kind") and returns the
/// kind. Throws naming the file for a foreign file, a newer version or a missing member.
inline std::string check_model_file(const JsonView& file) {
  if (file.type() != Json::Type::object) file.fail("a model file must be a JSON object, found " + detail::json_preview(file.json()));
  if (!file.contains("format")) file.fail("missing key 'format' at top level: not an nlid model file");
  const std::string& format = file.at("format").as_string();
  if (format != "nlid-model") {
    file.at("format").fail("not an nlid model file: format is \"" + format + "\", expected \"nlid-model\"");
  }
  const long long version = file.at("version").as_integer();
  if (version > model_file_version) {
    file.at("version").fail("model file version " + std::to_string(version) +
                            " is newer than this nlid can read (it reads versions 1 to " +
                            std::to_string(model_file_version) + "); update nlid");
  }
  if (version < 1) file.at("version").fail("model file version " + std::to_string(version) + " is invalid (versions start at 1)");
  return file.at("kind").as_string();
}

/// Reads and checks a model file (parse errors name file, line and column).
[[nodiscard]] inline Json read_model_file(const std::string& path) {
  Json j = read_json(path);
  (void)check_model_file(j.view());
  return j;
}

/// The metadata of a parsed model file (units, default initial condition, description, date).
[[nodiscard]] inline ModelFileInfo model_file_info(const JsonView& file) {
  ModelFileInfo info;
  std::vector<std::string> in, out;
  (void)detail::read_common(file, info, in, out);
  info.description = file.value_or<std::string>("description", "");
  info.created = file.value_or<std::string>("created", "");
  return info;
}

/// Builds a model of compile-time type M from parsed file JSON; `info` receives the metadata.
template <LoadableModel M>
[[nodiscard]] M model_from_json(const Json& j, ModelFileInfo* info = nullptr) {
  const JsonView file = j.view();
  (void)check_model_file(file);
  ModelFileInfo local = model_file_info(file);
  M m = ModelSerial<M>::load(file, local);
  if (info != nullptr) *info = std::move(local);
  return m;
}

/// Loads a model of compile-time type M (e.g. `Nlarx<LaggedRegressors<3,3,0>, SigmoidNet<6,5>>`).
/// Throws `nlid::Error` if the file's structure does not fit M, naming the key path.
template <LoadableModel M>
[[nodiscard]] M load_model(const std::string& path, ModelFileInfo* info = nullptr) {
  return model_from_json<M>(read_model_file(path), info);
}

/// Fills `prototype` (built in C++, e.g. with lambda custom regressors) from the file: checks that
/// the structure matches (regressor names, nonlinearity kind and sizes, physics) and copies
/// parameters, normalisation, sample time, channel names and report.
template <RestorableModel M>
void load_model(const std::string& path, M& prototype, ModelFileInfo* info = nullptr) {
  const Json j = read_model_file(path);
  const JsonView file = j.view();
  ModelFileInfo local = model_file_info(file);
  ModelSerial<M>::restore(file, prototype, local);
  if (info != nullptr) *info = std::move(local);
}

}  // namespace nlid
