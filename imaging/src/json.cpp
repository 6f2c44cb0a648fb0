#include "msk/imaging/json.h"

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <vector>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

namespace msk {

namespace {

/// "line L, column C: <what>" from a parse error of nlohmann (its text without the "[json.exception...] " prefix).
std::string parseProblem(const Json::parse_error& e) {
  std::string what = e.what();
  const size_t at = what.find("parse error at line ");
  if (at != std::string::npos) what = what.substr(at + 15);  // "line L, column C: ..."
  return what;
}

/// Throws Error naming the first non-finite number below `value` (its member path in `path`).
void requireFinite(const Json& value, const std::string& path) {
  if (value.is_number_float() && !std::isfinite(value.get<double>()))
    throw Error("JSON has no value for a non-finite number: " + (path.empty() ? std::string("(top)") : path) + " = " +
                std::to_string(value.get<double>()));
  if (value.is_object())
    for (const auto& item : value.items()) requireFinite(item.value(), path + (path.empty() ? "" : ".") + item.key());
  if (value.is_array())
    for (size_t i = 0; i < value.size(); ++i) requireFinite(value[i], path + "[" + std::to_string(i) + "]");
}

}  // namespace

Json parseJson(const std::string& text) {
  // Each open object's keys, to refuse a key given twice (nlohmann keeps the last one silently).
  std::vector<std::set<std::string>> keys;
  std::string duplicate;
  const Json::parser_callback_t watch = [&](int, Json::parse_event_t event, Json& parsed) {
    if (event == Json::parse_event_t::object_start) keys.emplace_back();
    if (event == Json::parse_event_t::object_end && !keys.empty()) keys.pop_back();
    if (event == Json::parse_event_t::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second &&
        duplicate.empty())
      duplicate = parsed.get<std::string>();
    return true;
  };
  Json out;
  try {
    out = Json::parse(text, watch);
  } catch (const Json::parse_error& e) {
    throw Error(parseProblem(e));
  } catch (const Json::exception& e) {
    // A number too large for a double ("number overflow parsing '1e999'") and the like: nlohmann's text
    // without its "[json.exception.<kind>.<id>] " prefix.
    std::string what = e.what();
    const size_t end = what.find("] ");
    throw Error(end == std::string::npos ? what : what.substr(end + 2));
  }
  if (!duplicate.empty()) throw Error("key \"" + duplicate + "\" given twice in one object");
  return out;
}

Json readJsonFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open file");
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) throw IoError(path, "read failed");
  try {
    return parseJson(text.str());
  } catch (const Error& e) {
    throw IoError(path, std::string("invalid JSON: ") + e.what());
  }
}

std::string dumpJson(const Json& value, int indent) {
  requireFinite(value, "");
  return value.dump(indent);
}

void writeJsonFile(const std::string& path, const Json& value) {
  const std::string text = dumpJson(value, 2) + "\n";
  writeAtomically(path, [&](const std::string& temp) {
    std::ofstream out(temp, std::ios::binary);
    if (!out) throw IoError(path, "cannot create file");
    out << text;
    out.close();
    if (!out) throw IoError(path, "write failed");
  });
}

const Json* jsonMember(const Json& obj, const std::string& key) {
  if (!obj.is_object()) return nullptr;
  const auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

int jsonInt(const Json& value) {
  if (!value.is_number()) throw Error(std::string("expected an integer, found ") + value.type_name());
  const double v = value.get<double>();
  if (v != std::floor(v) || v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    throw Error("expected an integer, found " + value.dump());
  return static_cast<int>(v);
}

}  // namespace msk
