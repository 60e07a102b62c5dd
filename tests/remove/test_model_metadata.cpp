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
  std::string load_error() { return load_error_of(Models::Graphs::all); }
  std::string load_error_of(Models::Graphs graphs) {
    try {
      SessionConfig config;
      config.threads = 1;
      Models m(tmp / "models", config, graphs);
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

// A second head's map (model.h: kAlternativeOutput) and the metadata that says whose it is come
// together: either alone is refused, naming the file; both are read.
TEST_F(ModelMetadata, AnAlternativeOutputAndItsNameComeTogether) {
  add("raindrop.alternative_detector", "compact-windshield-head");
  EXPECT_NE(expect_load_blames("raindrop.alternative_detector").find("alternative_mask_prob"), std::string::npos);

  const fs::path committed = source_dir() / "models" / "compact-multiscale" / "rdn.onnx";
  if (!fs::exists(committed)) GTEST_SKIP() << "the committed models are not in " << source_dir() / "models";
  const std::string graph = read_file(committed);
  SessionConfig config;
  config.threads = 1;
  fs::create_directories(tmp / "main");
  write_file(tmp / "main" / "rdn.onnx", graph);
  raindrop::removal::Network rdn(tmp / "main" / "rdn.onnx", "rdn", config);
  ASSERT_TRUE(rdn.has_alternative_output()) << "the default's detector carries compact-windshield-head's map";
  for (const char* f : {"rrn.onnx", "rfn.onnx"}) fs::copy_file(committed.parent_path() / f, tmp / "main" / f);
  EXPECT_EQ(Models(tmp / "main", config).info().alternative_detector, "compact-windshield-head");
  // Both maps in one run: the first is what the graph gives without the second.
  const int h = 24, w = 32;
  std::vector<float> image(3 * h * w), alone(h * w), both(2 * h * w);
  for (size_t i = 0; i < image.size(); ++i) image[i] = static_cast<float>((i * 7919) % 256) / 255.0f;
  rdn.run({image.data()}, h, w, alone.data());
  rdn.run({image.data()}, h, w, both.data(), both.data() + h * w);
  EXPECT_TRUE(std::equal(alone.begin(), alone.end(), both.begin()));
  EXPECT_FALSE(std::equal(alone.begin(), alone.end(), both.begin() + h * w)) << "two heads, two maps";

  // The name's key changed (same length): an output without its name.
  std::string unnamed = graph;
  const size_t at = unnamed.find("raindrop.alternative_detector");
  ASSERT_NE(at, std::string::npos);
  unnamed.replace(at, 8, "raindrox");
  write_file(tmp / "main" / "rdn.onnx", unnamed);
  try {
    Models m(tmp / "main", config);
    ADD_FAILURE() << "a second output without its name was accepted";
  } catch (const raindrop::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("rdn.onnx"), std::string::npos) << msg;
    EXPECT_NE(msg.find("raindrop.alternative_detector"), std::string::npos) << msg;
  }
  // A graph without the second output is refused a request for it.
  raindrop::removal::Network smoke(smoke_models() / "rdn.onnx", "rdn", config);
  EXPECT_FALSE(smoke.has_alternative_output());
  EXPECT_THROW(smoke.run({image.data()}, h, w, alone.data(), both.data()), raindrop::Error);
}

// A detector loaded for its metadata only (a router's alternative whose map the main graph
// computes) gives what a session gives, and refuses a file that is not a model, naming it.
TEST_F(ModelMetadata, MetadataWithoutASessionIsTheSessionsMetadata) {
  add("raindrop.surround_fill_area", "1500");
  SessionConfig config;
  config.threads = 1;
  const Models session(tmp / "models", config, Models::Graphs::detection);
  const Models meta(tmp / "models", config, Models::Graphs::metadata);
  EXPECT_EQ(meta.info().config, session.info().config);
  EXPECT_EQ(meta.info().threshold, session.info().threshold);
  EXPECT_EQ(meta.info().dilation, session.info().dilation);
  EXPECT_EQ(meta.info().pad_multiple, session.info().pad_multiple);
  EXPECT_EQ(meta.info().surround_fill_area, 1500);
  EXPECT_THROW(const_cast<Models&>(meta).rdn_beside(), raindrop::Error) << "no graph to run";
  set("raindrop.dilation", "99999");
  EXPECT_NE(std::string(load_error_of(Models::Graphs::metadata)).find("raindrop.dilation"), std::string::npos);
  for (const std::string& bad : {std::string("not a model"), std::string("\x72\x7f", 2)}) {
    write_file(tmp / "models" / "rdn.onnx", bad);
    const std::string e = load_error_of(Models::Graphs::metadata);
    EXPECT_NE(e.find("rdn.onnx"), std::string::npos) << e;
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
