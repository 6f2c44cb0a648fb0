#pragma once
/// JSON documents (scene files, reports): nlohmann::ordered_json, which keeps keys in insertion order and writes
/// doubles so that they read back bit for bit, with the project's strict reading and writing rules.
#include <nlohmann/json.hpp>
#include <string>

namespace msk {

/// A JSON value; object keys keep their insertion order.
using Json = nlohmann::ordered_json;

/// Parses `text`; a syntax error, a duplicate key in an object, or trailing text throws Error
/// "line L, column C: <problem>".
Json parseJson(const std::string& text);

/// Reads and parses a file; throws IoError naming the file (and the line and column of a syntax error).
Json readJsonFile(const std::string& path);

/// The document as text: pretty with `indent` spaces (one line if indent < 0). Throws Error naming the member (as
/// `a.b[2].c`) of the first number that is not finite: JSON has no NaN or infinity, and nothing is written as null in
/// their place.
std::string dumpJson(const Json& value, int indent = 2);

/// Writes dumpJson(value) and a newline to `path` atomically (temporary file, then rename); throws IoError naming
/// the file.
void writeJsonFile(const std::string& path, const Json& value);

/// Member `key` of object `obj`, or nullptr if `obj` is not an object or has no such member.
const Json* jsonMember(const Json& obj, const std::string& key);

/// The number `value` as an int; throws Error if it is not a number, not whole, or outside the int range.
int jsonInt(const Json& value);

}  // namespace msk
