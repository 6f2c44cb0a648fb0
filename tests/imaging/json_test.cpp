#include "msk/imaging/json.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "msk/core/error.h"
#include "msk/test/files.h"

using msk::Json;

TEST(Json, ParsesNestedDocumentKeepingKeyOrder) {
  const Json j = msk::parseJson(R"({"z": 1, "objects": [{"name": "femur", "label": 1, "w": -2.5e-1, "ok": true}],
                                   "s": "a\"b\u00e9"})");
  ASSERT_TRUE(j.is_object());
  EXPECT_EQ(j.begin().key(), "z");  // insertion order, not sorted
  const Json& o = j.at("objects").at(0);
  EXPECT_EQ(o.at("name").get<std::string>(), "femur");
  EXPECT_EQ(msk::jsonInt(o.at("label")), 1);
  EXPECT_DOUBLE_EQ(o.at("w").get<double>(), -0.25);
  EXPECT_TRUE(o.at("ok").get<bool>());
  EXPECT_EQ(j.at("s").get<std::string>(), "a\"b\xc3\xa9");
  EXPECT_NE(msk::jsonMember(o, "label"), nullptr);
  EXPECT_EQ(msk::jsonMember(o, "lable"), nullptr);
  EXPECT_EQ(msk::jsonMember(j.at("objects"), "name"), nullptr);  // not an object
}

TEST(Json, DoublesRoundTripBitForBit) {
  Json j = Json::array();
  for (double v : {0.1, 1.0 / 3.0, 6.02214076e23, -4.9e-324, 123456789.123456789}) j.push_back(v);
  const Json k = msk::parseJson(msk::dumpJson(j, 2));
  for (size_t i = 0; i < j.size(); ++i) EXPECT_EQ(k[i].get<double>(), j[i].get<double>()) << i;
}

TEST(Json, ErrorsGiveLineAndColumn) {
  try {
    msk::parseJson("{\n  \"a\": 1,\n  \"b\" 2\n}");
    FAIL() << "no error";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3, column"), std::string::npos) << e.what();
  }
  EXPECT_THROW(msk::parseJson("{\"a\":1,\"a\":2}"), msk::Error);  // a key given twice
  EXPECT_THROW(msk::parseJson("{\"o\": {\"a\":1, \"b\": {}, \"a\":2}}"), msk::Error);
  EXPECT_NO_THROW(msk::parseJson("[{\"a\":1}, {\"a\":2}]"));  // the same key in two objects is fine
  EXPECT_THROW(msk::parseJson("[1,]"), msk::Error);
  try {  // a number beyond a double is an msk::Error too, not nlohmann's own exception
    msk::parseJson("{\"a\": 1e99999}");
    ADD_FAILURE() << "a number beyond a double was accepted";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("number overflow parsing '1e99999'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(msk::parseJson("1 2"), msk::Error);
  EXPECT_THROW(msk::parseJson("\"unterminated"), msk::Error);
  EXPECT_THROW(msk::jsonInt(msk::parseJson("1.5")), msk::Error);
  EXPECT_THROW(msk::jsonInt(msk::parseJson("\"x\"")), msk::Error);
}

TEST(Json, NonFiniteNumbersAreRefusedNamingTheMember) {
  Json j;
  j["objects"] = Json::array({Json::object()});
  j["objects"][0]["volume_change_percent"] = std::numeric_limits<double>::quiet_NaN();
  try {
    msk::dumpJson(j);
    FAIL() << "NaN written";
  } catch (const msk::Error& e) {
    EXPECT_NE(std::string(e.what()).find("objects[0].volume_change_percent"), std::string::npos) << e.what();
  }
  j["objects"][0]["volume_change_percent"] = INFINITY;
  EXPECT_THROW(msk::dumpJson(j), msk::Error);
}

TEST(Json, FilesAreNamedInErrorsAndWrittenAtomically) {
  msk::test::ScratchDir dir;
  msk::test::writeBytes(dir.file("bad.json"), "{\"a\": }");
  try {
    msk::readJsonFile(dir.file("bad.json"));
    FAIL() << "no error";
  } catch (const msk::IoError& e) {
    EXPECT_EQ(e.file(), dir.file("bad.json"));
    EXPECT_NE(e.problem().find("line 1"), std::string::npos) << e.problem();
  }
  EXPECT_THROW(msk::readJsonFile(dir.file("missing.json")), msk::IoError);
  Json j;
  j["k"] = 3;
  msk::writeJsonFile(dir.file("ok.json"), j);
  EXPECT_EQ(msk::jsonInt(msk::readJsonFile(dir.file("ok.json")).at("k")), 3);
  j["bad"] = std::nan("");
  EXPECT_THROW(msk::writeJsonFile(dir.file("nan.json"), j), msk::Error);
  EXPECT_EQ(dir.list().size(), 2u);  // bad.json and ok.json: no temporary, no nan.json
}
