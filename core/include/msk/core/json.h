#pragma once
/// A small JSON value with a strict parser (errors give line and column) and a pretty writer.
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace msk {

/// One JSON value: null, bool, number, string, array or object (keys kept in insertion order).
class Json {
 public:
  /// The JSON kinds.
  enum class Type { Null, Bool, Number, String, Array, Object };
  using Array = std::vector<Json>;
  using Object = std::vector<std::pair<std::string, Json>>;

  Json() = default;
  Json(std::nullptr_t) {}
  Json(bool b) : type_(Type::Bool), bool_(b) {}
  Json(int v) : type_(Type::Number), num_(v) {}
  Json(long v) : type_(Type::Number), num_(static_cast<double>(v)) {}
  Json(long long v) : type_(Type::Number), num_(static_cast<double>(v)) {}
  Json(unsigned v) : type_(Type::Number), num_(v) {}
  Json(unsigned long v) : type_(Type::Number), num_(static_cast<double>(v)) {}
  Json(double v) : type_(Type::Number), num_(v) {}
  Json(const char* s) : type_(Type::String), str_(s) {}
  Json(std::string s) : type_(Type::String), str_(std::move(s)) {}
  Json(Array a) : type_(Type::Array), arr_(std::make_shared<Array>(std::move(a))) {}
  Json(Object o) : type_(Type::Object), obj_(std::make_shared<Object>(std::move(o))) {}

  /// An empty object.
  static Json object() { return Json(Object{}); }
  /// An empty array.
  static Json array() { return Json(Array{}); }

  Type type() const { return type_; }
  bool isNull() const { return type_ == Type::Null; }
  bool isBool() const { return type_ == Type::Bool; }
  bool isNumber() const { return type_ == Type::Number; }
  bool isString() const { return type_ == Type::String; }
  bool isArray() const { return type_ == Type::Array; }
  bool isObject() const { return type_ == Type::Object; }
  /// Name of the kind ("object", "number", ...), for error messages.
  const char* typeName() const;

  /// Accessors; throw msk::Error naming the expected and actual kind on mismatch.
  bool asBool() const;
  double asNumber() const;
  /// The number as an int; throws if it is not integral or out of range.
  int asInt() const;
  const std::string& asString() const;
  const Array& asArray() const;
  Array& asArray();
  const Object& asObject() const;
  Object& asObject();

  /// Object member or nullptr.
  const Json* find(const std::string& key) const;
  /// Object member; throws if missing.
  const Json& at(const std::string& key) const;
  /// Object member, inserted as null if missing (turns a null value into an object).
  Json& operator[](const std::string& key);
  /// Appends to an array (turns a null value into an array).
  void push(Json v);
  /// Number of array elements or object members.
  size_t size() const;

  /// Parses text; throws msk::Error "line L, column C: problem".
  static Json parse(const std::string& text);
  /// Reads and parses a file; throws IoError naming the file, line and column.
  static Json readFile(const std::string& path);
  /// Serialises; indent < 0 gives one line, otherwise pretty with that many spaces.
  std::string dump(int indent = 2) const;
  /// Writes atomically to a file (pretty, trailing newline).
  void writeFile(const std::string& path) const;

 private:
  void dumpTo(std::string& out, int indent, int depth) const;
  Type type_ = Type::Null;
  bool bool_ = false;
  double num_ = 0;
  std::string str_;
  std::shared_ptr<Array> arr_;
  std::shared_ptr<Object> obj_;
};

}  // namespace msk
