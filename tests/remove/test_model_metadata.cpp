// Model metadata out of range (rdn.onnx's raindrop.threshold, raindrop.dilation and optional
// raindrop.large_drop_growth): refused when the models load, with one line that blames the model
// file's metadata, not an option.
#include "raindrop/common/error.h"
#include "raindrop/remove/model.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

using raindrop::removal::Models;
using raindrop::removal::SessionConfig;

// `model` (an ONNX file's bytes) with the value of metadata entry `key` replaced. Each entry
// is a top-level ModelProto field 14 (tag 0x72), a message {1: key, 2: value}; the smoke
// models' entries are short, so every length is one byte.
std::string with_metadata(const std::string& model, const std::string& key, const std::string& value) {
  const std::string key_field = std::string{'\x0a', static_cast<char>(key.size())} + key;
  const size_t at = model.find(key_field);
  EXPECT_NE(at, std::string::npos) << key;
  EXPECT_GE(at, 2u);
  const size_t entry = at - 2;
  EXPECT_EQ(model[entry], '\x72');
  const size_t old_len = static_cast<unsigned char>(model[entry + 1]);
  const std::string body = key_field + std::string{'\x12', static_cast<char>(value.size())} + value;
  EXPECT_LT(body.size(), 128u);
  return model.substr(0, entry) + '\x72' + static_cast<char>(body.size()) + body + model.substr(entry + 2 + old_len);
}

class ModelMetadata : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(tmp / "models");
    for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) fs::copy_file(smoke_models() / f, tmp / "models" / f);
  }
  void set(const std::string& key, const std::string& value) {
    write_file(tmp / "models" / "rdn.onnx", with_metadata(read_file(smoke_models() / "rdn.onnx"), key, value));
  }
  void add(const std::string& key, const std::string& value) {
    write_file(tmp / "models" / "rdn.onnx", with_added_metadata(read_file(smoke_models() / "rdn.onnx"), key, value));
  }
  std::string load_error() {
    try {
      SessionConfig config;
      config.threads = 1;
      Models m(tmp / "models", config);
    } catch (const raindrop::Error& e) {
      return e.what();
    }
    return "";
  }
  // Loading fails with one message that names rdn.onnx and `key`; returns it.
  std::string expect_load_blames(const std::string& key) {
    const std::string e = load_error();
    EXPECT_NE(e.find("rdn.onnx"), std::string::npos) << e;
    EXPECT_NE(e.find(key), std::string::npos) << e;
    return e;
  }
  TempDir tmp;
};

TEST_F(ModelMetadata, TheEditedCopyLoads) {
  set("raindrop.dilation", "7");
  SessionConfig config;
  config.threads = 1;
  EXPECT_EQ(Models(tmp / "models", config).info().dilation, 7) << "the edit did not take";
}

TEST_F(ModelMetadata, DilationOutOfRangeBlamesTheModel) {
  for (const std::string v : {"99999", "1024", "0"}) {
    SCOPED_TRACE(v);
    set("raindrop.dilation", v);
    const std::string e = expect_load_blames("raindrop.dilation");
    EXPECT_EQ(e.find("--dilation"), std::string::npos) << "the option was not given: " << e;
  }
}

TEST_F(ModelMetadata, LargeDropGrowthIsReadAndZeroWhenAbsent) {
  SessionConfig config;
  config.threads = 1;
  EXPECT_EQ(Models(tmp / "models", config).info().large_drop_growth, 0.0);
  add("raindrop.large_drop_growth", "0.35");
  EXPECT_EQ(Models(tmp / "models", config).info().large_drop_growth, 0.35) << "the added entry did not take";
}

TEST_F(ModelMetadata, LargeDropGrowthOutOfRangeBlamesTheModel) {
  for (const std::string v : {"-0.1", "10.5", "nan", "x"}) {
    SCOPED_TRACE(v);
    add("raindrop.large_drop_growth", v);
    expect_load_blames("raindrop.large_drop_growth");
  }
}

TEST_F(ModelMetadata, SurroundFillAreaIsReadAndTheDefaultWhenAbsent) {
  SessionConfig config;
  config.threads = 1;
  EXPECT_EQ(Models(tmp / "models", config).info().surround_fill_area, raindrop::removal::kSurroundFillArea);
  add("raindrop.surround_fill_area", "1500");
  EXPECT_EQ(Models(tmp / "models", config).info().surround_fill_area, 1500) << "the added entry did not take";
  add("raindrop.surround_fill_area", "0");
  EXPECT_EQ(Models(tmp / "models", config).info().surround_fill_area, 0) << "0 (off) is a valid area";
}

TEST_F(ModelMetadata, SurroundFillAreaOutOfRangeBlamesTheModel) {
  for (const std::string v : {"-1", "1.5", "x", "99999999999"}) {
    SCOPED_TRACE(v);
    add("raindrop.surround_fill_area", v);
    const std::string e = expect_load_blames("raindrop.surround_fill_area");
    EXPECT_EQ(e.find("--surround-fill-area"), std::string::npos) << "the option was not given: " << e;
  }
}

TEST_F(ModelMetadata, ThresholdOutsideZeroOneIsRefused) {
  for (const std::string v : {"2", "1", "0", "-0.5"}) {
    SCOPED_TRACE(v);
    set("raindrop.threshold", v);
    expect_load_blames("raindrop.threshold");
  }
}

// End to end: one line, exit code 1, no output.
TEST_F(ModelMetadata, TheProgramSaysItInOneLine) {
  write_image(tmp / "in.png", make_image(40, 30, 1));
  set("raindrop.dilation", "99999");
  const RunResult r = run_remove({"in.png", "out.png", "--models", "models"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  ASSERT_EQ(split_lines(r.err).size(), 1u) << r.describe();
  EXPECT_NE(r.err.find("raindrop.dilation"), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find("--dilation"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out.png"));
}

}  // namespace
}  // namespace removetest
