#include "msk/core/json.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "msk/core/atomic_file.h"
#include "msk/core/error.h"

namespace msk {

const char* Json::typeName() const {
  switch (type_) {
    case Type::Null: return "null";
    case Type::Bool: return "boolean";
    case Type::Number: return "number";
    case Type::String: return "string";
    case Type::Array: return "array";
    case Type::Object: return "object";
  }
  return "?";
}

namespace {
[[noreturn]] void kindError(const char* want, const Json& j) {
  throw Error(std::string("expected a JSON ") + want + ", found " + j.typeName());
}
}  // namespace

bool Json::asBool() const {
  if (!isBool()) kindError("boolean", *this);
  return bool_;
}
double Json::asNumber() const {
  if (!isNumber()) kindError("number", *this);
  return num_;
}
int Json::asInt() const {
  double v = asNumber();
  if (v != std::floor(v) || v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max())
    throw Error("expected an integer, found " + dump(-1));
  return static_cast<int>(v);
}
const std::string& Json::asString() const {
  if (!isString()) kindError("string", *this);
  return str_;
}
const Json::Array& Json::asArray() const {
  if (!isArray()) kindError("array", *this);
  return *arr_;
}
Json::Array& Json::asArray() {
  if (!isArray()) kindError("array", *this);
  return *arr_;
}
const Json::Object& Json::asObject() const {
  if (!isObject()) kindError("object", *this);
  return *obj_;
}
Json::Object& Json::asObject() {
  if (!isObject()) kindError("object", *this);
  return *obj_;
}

const Json* Json::find(const std::string& key) const {
  for (const auto& kv : asObject())
    if (kv.first == key) return &kv.second;
  return nullptr;
}
const Json& Json::at(const std::string& key) const {
  const Json* j = find(key);
  if (!j) throw Error("missing key \"" + key + "\"");
  return *j;
}
Json& Json::operator[](const std::string& key) {
  if (isNull()) *this = object();
  for (auto& kv : asObject())
    if (kv.first == key) return kv.second;
  obj_->emplace_back(key, Json());
  return obj_->back().second;
}
void Json::push(Json v) {
  if (isNull()) *this = array();
  asArray().push_back(std::move(v));
}
size_t Json::size() const {
  if (isArray()) return arr_->size();
  if (isObject()) return obj_->size();
  return 0;
}

// ---------------------------------------------------------------- parser
namespace {
class Parser {
 public:
  explicit Parser(const std::string& t) : s_(t) {}
  Json parseDocument() {
    skipWs();
    Json v = parseValue(0);
    skipWs();
    if (p_ != s_.size()) fail("unexpected text after the JSON value");
    return v;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    size_t line = 1, col = 1;
    for (size_t i = 0; i < p_ && i < s_.size(); ++i) {
      if (s_[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    throw Error("line " + std::to_string(line) + ", column " + std::to_string(col) + ": " + what);
  }
  void skipWs() {
    while (p_ < s_.size() && (s_[p_] == ' ' || s_[p_] == '\t' || s_[p_] == '\n' || s_[p_] == '\r')) ++p_;
  }
  bool consume(const char* word) {
    size_t n = std::char_traits<char>::length(word);
    if (s_.compare(p_, n, word) == 0) {
      p_ += n;
      return true;
    }
    return false;
  }
  Json parseValue(int depth) {
    if (depth > 200) fail("nesting too deep");
    if (p_ >= s_.size()) fail("unexpected end of input");
    char c = s_[p_];
    if (c == '{') return parseObject(depth);
    if (c == '[') return parseArray(depth);
    if (c == '"') return Json(parseString());
    if (consume("true")) return Json(true);
    if (consume("false")) return Json(false);
    if (consume("null")) return Json();
    if (c == '-' || (c >= '0' && c <= '9')) return parseNumber();
    fail(std::string("unexpected character '") + c + "'");
  }
  Json parseObject(int depth) {
    ++p_;
    Json::Object obj;
    skipWs();
    if (p_ < s_.size() && s_[p_] == '}') {
      ++p_;
      return Json(std::move(obj));
    }
    for (;;) {
      skipWs();
      if (p_ >= s_.size() || s_[p_] != '"') fail("expected a string key");
      std::string key = parseString();
      for (const auto& kv : obj)
        if (kv.first == key) fail("duplicate key \"" + key + "\"");
      skipWs();
      if (p_ >= s_.size() || s_[p_] != ':') fail("expected ':' after key \"" + key + "\"");
      ++p_;
      skipWs();
      obj.emplace_back(std::move(key), parseValue(depth + 1));
      skipWs();
      if (p_ < s_.size() && s_[p_] == ',') {
        ++p_;
        continue;
      }
      if (p_ < s_.size() && s_[p_] == '}') {
        ++p_;
        return Json(std::move(obj));
      }
      fail("expected ',' or '}' in object");
    }
  }
  Json parseArray(int depth) {
    ++p_;
    Json::Array arr;
    skipWs();
    if (p_ < s_.size() && s_[p_] == ']') {
      ++p_;
      return Json(std::move(arr));
    }
    for (;;) {
      skipWs();
      arr.push_back(parseValue(depth + 1));
      skipWs();
      if (p_ < s_.size() && s_[p_] == ',') {
        ++p_;
        continue;
      }
      if (p_ < s_.size() && s_[p_] == ']') {
        ++p_;
        return Json(std::move(arr));
      }
      fail("expected ',' or ']' in array");
    }
  }
  static void appendUtf8(std::string& out, unsigned cp) {
    if (cp < 0x80) {
      out += static_cast<char>(cp);
    } else if (cp < 0x800) {
      out += static_cast<char>(0xC0 | (cp >> 6));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      out += static_cast<char>(0xE0 | (cp >> 12));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (cp >> 18));
      out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (cp & 0x3F));
    }
  }
  unsigned parseHex4() {
    if (p_ + 4 > s_.size()) fail("truncated \\u escape");
    unsigned v = 0;
    for (int i = 0; i < 4; ++i) {
      char c = s_[p_++];
      v <<= 4;
      if (c >= '0' && c <= '9') v |= c - '0';
      else if (c >= 'a' && c <= 'f') v |= c - 'a' + 10;
      else if (c >= 'A' && c <= 'F') v |= c - 'A' + 10;
      else fail("bad \\u escape");
    }
    return v;
  }
  std::string parseString() {
    ++p_;
    std::string out;
    for (;;) {
      if (p_ >= s_.size()) fail("unterminated string");
      char c = s_[p_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) fail("control character in string");
      if (c != '\\') {
        out += c;
        continue;
      }
      if (p_ >= s_.size()) fail("unterminated string");
      char e = s_[p_++];
      switch (e) {
        case '"': out += '"'; break;
        case '\\': out += '\\'; break;
        case '/': out += '/'; break;
        case 'b': out += '\b'; break;
        case 'f': out += '\f'; break;
        case 'n': out += '\n'; break;
        case 'r': out += '\r'; break;
        case 't': out += '\t'; break;
        case 'u': {
          unsigned cp = parseHex4();
          if (cp >= 0xD800 && cp < 0xDC00 && consume("\\u")) {
            unsigned lo = parseHex4();
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          }
          appendUtf8(out, cp);
          break;
        }
        default: fail(std::string("bad escape '\\") + e + "'");
      }
    }
  }
  Json parseNumber() {
    size_t start = p_;
    if (s_[p_] == '-') ++p_;
    auto digits = [&] {
      size_t b = p_;
      while (p_ < s_.size() && s_[p_] >= '0' && s_[p_] <= '9') ++p_;
      return p_ - b;
    };
    if (digits() == 0) fail("malformed number");
    if (p_ < s_.size() && s_[p_] == '.') {
      ++p_;
      if (digits() == 0) fail("malformed number");
    }
    if (p_ < s_.size() && (s_[p_] == 'e' || s_[p_] == 'E')) {
      ++p_;
      if (p_ < s_.size() && (s_[p_] == '+' || s_[p_] == '-')) ++p_;
      if (digits() == 0) fail("malformed number");
    }
    std::istringstream in(s_.substr(start, p_ - start));
    in.imbue(std::locale::classic());
    double v = 0;
    in >> v;
    if (!std::isfinite(v)) fail("number out of range");
    return Json(v);
  }
  const std::string& s_;
  size_t p_ = 0;
};

void dumpString(std::string& out, const std::string& s) {
  out += '"';
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  out += '"';
}
}  // namespace

Json Json::parse(const std::string& text) { return Parser(text).parseDocument(); }

Json Json::readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  try {
    return parse(ss.str());
  } catch (const IoError&) {
    throw;
  } catch (const Error& e) {
    throw IoError(path, std::string("invalid JSON: ") + e.what());
  }
}

void Json::dumpTo(std::string& out, int indent, int depth) const {
  auto newline = [&](int d) {
    if (indent < 0) return;
    out += '\n';
    out.append(static_cast<size_t>(indent * d), ' ');
  };
  switch (type_) {
    case Type::Null: out += "null"; break;
    case Type::Bool: out += bool_ ? "true" : "false"; break;
    case Type::Number: {
      if (!std::isfinite(num_)) {
        out += "null";
      } else if (num_ == std::floor(num_) && std::fabs(num_) < 1e15) {
        out += std::to_string(static_cast<long long>(num_));
      } else {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%.10g", num_);
        out += buf;
      }
      break;
    }
    case Type::String: dumpString(out, str_); break;
    case Type::Array: {
      out += '[';
      bool scalarOnly = true;
      for (const auto& v : *arr_) scalarOnly = scalarOnly && !v.isArray() && !v.isObject();
      for (size_t i = 0; i < arr_->size(); ++i) {
        if (i) out += scalarOnly || indent < 0 ? ", " : ",";
        if (!scalarOnly) newline(depth + 1);
        (*arr_)[i].dumpTo(out, indent, depth + 1);
      }
      if (!scalarOnly && !arr_->empty()) newline(depth);
      out += ']';
      break;
    }
    case Type::Object: {
      out += '{';
      for (size_t i = 0; i < obj_->size(); ++i) {
        if (i) out += ',';
        newline(depth + 1);
        dumpString(out, (*obj_)[i].first);
        out += indent < 0 ? ":" : ": ";
        (*obj_)[i].second.dumpTo(out, indent, depth + 1);
      }
      if (!obj_->empty()) newline(depth);
      out += '}';
      break;
    }
  }
}

std::string Json::dump(int indent) const {
  std::string out;
  dumpTo(out, indent, 0);
  return out;
}

void Json::writeFile(const std::string& path) const {
  writeAtomically(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw IoError(path, "cannot create file");
    out << dump(2) << '\n';
    out.close();
    if (!out) throw IoError(path, "write failed");
  });
}

}  // namespace msk
