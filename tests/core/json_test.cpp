#include "msk/core/json.h"

#include <gtest/gtest.h>

#include "msk/core/error.h"
#include "test_support.h"

using msk::Json;

TEST(Json, ParsesNestedDocument) {
  Json j = Json::parse(R"({"objects": [{"name": "femur", "label": 1, "w": -2.5e-1, "ok": true, "n": null}],
                          "s": "a\"b\u00e9"})");
  ASSERT_TRUE(j.isObject());
  const Json& o = j.at("objects").asArray().at(0);
  EXPECT_EQ(o.at("name").asString(), "femur");
  EXPECT_EQ(o.at("label").asInt(), 1);
  EXPECT_DOUBLE_EQ(o.at("w").asNumber(), -0.25);
  EXPECT_TRUE(o.at("ok").asBool());
  EXPECT_TRUE(o.at("n").isNull());
  EXPECT_EQ(j.at("s").asString(), "a\"b\xc3\xa9");
}

TEST(Json, RoundTripsThroughDump) {
  Json j;
  j["a"] = 1.5;
  j["b"].push("x");
  j["b"].push(Json::object());
  j["c"] = Json(std::string("line\nbreak"));
  Json k = Json::parse(j.dump(2));
  EXPECT_EQ(k.dump(-1), j.dump(-1));
  EXPECT_EQ(Json::parse(j.dump(-1)).dump(2), j.dump(2));
}

TEST(Json, ErrorsGiveLineAndColumn) {
  try {
    Json::parse("{\n  \"a\": 1,\n  \"b\" 2\n}");
    FAIL() << "no error";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Json::parse("{\"a\":1,\"a\":2}"), msk::Error);
  EXPECT_THROW(Json::parse("[1,]"), msk::Error);
  EXPECT_THROW(Json::parse("1 2"), msk::Error);
  EXPECT_THROW(Json::parse("\"unterminated"), msk::Error);
  EXPECT_THROW(Json::parse("1.5").asInt(), msk::Error);
  EXPECT_THROW(Json::parse("\"x\"").asNumber(), msk::Error);
}

TEST(Json, ReadFileNamesTheFile) {
  msk::test::ScratchDir dir;
  msk::test::writeBytes(dir.file("bad.json"), "{\"a\": }");
  try {
    Json::readFile(dir.file("bad.json"));
    FAIL() << "no error";
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), dir.file("bad.json"));
  }
  EXPECT_THROW(Json::readFile(dir.file("missing.json")), msk::IoError);
  Json j;
  j["k"] = 3;
  j.writeFile(dir.file("ok.json"));
  EXPECT_EQ(Json::readFile(dir.file("ok.json")).at("k").asInt(), 3);
  EXPECT_EQ(dir.list().size(), 2u);  // no temporary left behind
}
