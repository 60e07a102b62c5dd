// End-to-end: determinism across thread counts and the data-set contract
// (docs/CONTRACTS.md section 1) checked on real files written by raindrop-render.
#include <cmath>
#include <set>

#include "cli_test_util.h"
#include "raindrop/render/render_job.h"

namespace clitest {
namespace {

// Four generated inputs of different sizes and aspect ratios (landscape 4:3, 2:1, portrait,
// small) in <root>/in.
void make_inputs(const fs::path& root) {
  write_image(root / "in" / "a_street.png", make_background(640, 480, 0));
  write_image(root / "in" / "b_checker.png", make_background(512, 256, 1));
  write_image(root / "in" / "c_portrait.png", make_background(300, 400, 2));
  write_image(root / "in" / "d_small.png", make_background(200, 120, 3));
}
const std::set<std::string> kInputStems = {"a_street", "b_checker", "c_portrait", "d_small"};

// What the contract says clean/<id>.png holds: the input, centre-cropped to the output's
// aspect ratio and resized (area averaging down, bilinear up), or the input itself.
cv::Mat expected_clean(const cv::Mat& input, std::optional<cv::Size> size) {
  if (!size || *size == input.size()) return input;
  const double aspect = static_cast<double>(size->width) / size->height;
  int w = input.cols, h = input.rows;
  if (static_cast<double>(w) / h > aspect) {
    w = static_cast<int>(std::lround(h * aspect));
  } else {
    h = static_cast<int>(std::lround(w / aspect));
  }
  const cv::Rect window((input.cols - w) / 2, (input.rows - h) / 2, w, h);
  cv::Mat out;
  cv::resize(input(window), out, *size, 0, 0, size->width < w ? cv::INTER_AREA : cv::INTER_LINEAR);
  return out;
}

void expect_number(const json& j, const char* key, const std::string& where) {
  ASSERT_TRUE(j.contains(key)) << where << ": no '" << key << "'";
  EXPECT_TRUE(j.at(key).is_number()) << where << ": '" << key << "' is " << j.at(key).dump();
}

// Checks every record of <out>/manifest.jsonl and its three images.
void check_dataset(const fs::path& cwd, const fs::path& out, std::optional<cv::Size> size, std::uint64_t run_seed,
                   int variants) {
  const auto lines = manifest_lines(out);
  ASSERT_EQ(lines.size(), kInputStems.size() * variants) << "manifest of " << out;
  std::string previous_id;
  std::set<std::string> sample_names;
  for (size_t n = 0; n < lines.size(); ++n) {
    SCOPED_TRACE("manifest line " + std::to_string(n + 1));
    const json r = json::parse(lines[n]);
    ASSERT_TRUE(r.is_object());
    // Keys and types from CONTRACTS.md.
    for (const char* key : {"id", "rainy", "clean", "mask", "source", "split", "renderer"}) {
      ASSERT_TRUE(r.contains(key) && r.at(key).is_string()) << "'" << key << "' missing or not a string: " << lines[n];
    }
    for (const char* key : {"width", "height", "variant", "seed"}) {
      ASSERT_TRUE(r.contains(key) && r.at(key).is_number_integer()) << "'" << key << "' missing or not an int";
    }
    ASSERT_TRUE(r.contains("coverage") && r.at("coverage").is_number());
    ASSERT_TRUE(r.contains("camera") && r.at("camera").is_object());
    for (const char* key : {"fx", "fy", "cx", "cy"}) expect_number(r.at("camera"), key, "camera");
    ASSERT_TRUE(r.at("camera").contains("origin"));
    EXPECT_EQ(r.at("camera").at("origin"), "default");
    ASSERT_TRUE(r.contains("scene") && r.at("scene").is_object());
    for (const char* key : {"glass_distance_cm", "background_distance_cm", "tilt_deg", "blur_diameter_px"})
      expect_number(r.at("scene"), key, "scene");
    ASSERT_TRUE(r.contains("effects") && r.at("effects").is_array());
    ASSERT_FALSE(r.at("effects").empty());
    for (const auto& e : r.at("effects")) EXPECT_TRUE(e.is_string());
    EXPECT_NE(std::find(r.at("effects").begin(), r.at("effects").end(), json("refraction")), r.at("effects").end());
    ASSERT_TRUE(r.contains("drops") && r.at("drops").is_array());
    ASSERT_FALSE(r.at("drops").empty()) << "the paper scene places 50-70 drops";
    for (const auto& d : r.at("drops")) {
      ASSERT_TRUE(d.is_object());
      ASSERT_TRUE(d.contains("center_cm") && d.at("center_cm").is_array() && d.at("center_cm").size() == 2);
      for (const char* key : {"footprint_radius_cm", "sphere_radius_cm", "contact_angle_deg"}) expect_number(d, key, "drop");
    }
    EXPECT_EQ(r.at("renderer"), "raindrop-render " + raindrop::renderer_version());
    EXPECT_EQ(r.at("split"), "none");

    // Ids: sorted, unique, "<source id>_v<variant>", files named after them.
    const std::string id = r.at("id");
    EXPECT_LT(previous_id, id) << "manifest not sorted by id (or duplicate id)";
    previous_id = id;
    const int variant = r.at("variant");
    EXPECT_GE(variant, 0);
    EXPECT_LT(variant, variants);
    const fs::path source = r.at("source").get<std::string>();
    const std::string stem = source.stem().string();
    EXPECT_TRUE(kInputStems.count(stem)) << "source " << source;
    const auto v_at = id.rfind("_v");
    ASSERT_NE(v_at, std::string::npos) << id;
    EXPECT_EQ(id.substr(0, v_at), stem);
    EXPECT_EQ(std::stoi(id.substr(v_at + 2)), variant) << id;
    EXPECT_EQ(r.at("seed").get<std::uint64_t>(), raindrop::sample_seed(run_seed, stem, variant));
    EXPECT_EQ(r.at("rainy"), "rainy/" + id + ".png");
    EXPECT_EQ(r.at("clean"), "clean/" + id + ".png");
    EXPECT_EQ(r.at("mask"), "mask/" + id + ".png");
    for (const char* kind : {"rainy", "clean", "mask"}) sample_names.insert(r.at(kind).get<std::string>());

    // The images.
    const int width = r.at("width"), height = r.at("height");
    std::string why;
    const auto rainy = read_image(out / r.at("rainy").get<std::string>(), &why);
    ASSERT_TRUE(rainy) << "rainy: " << why;
    const auto clean = read_image(out / r.at("clean").get<std::string>(), &why);
    ASSERT_TRUE(clean) << "clean: " << why;
    const auto mask = read_image(out / r.at("mask").get<std::string>(), &why);
    ASSERT_TRUE(mask) << "mask: " << why;
    for (const auto* img : {&rainy, &clean}) {
      EXPECT_EQ((*img)->width, width);
      EXPECT_EQ((*img)->height, height);
      EXPECT_EQ((*img)->channels, 3) << image_summary(*img);
      EXPECT_EQ((*img)->format, OIIO::TypeDesc::UINT8) << image_summary(*img);
    }
    EXPECT_EQ(mask->width, width);
    EXPECT_EQ(mask->height, height);
    ASSERT_EQ(mask->channels, 1) << image_summary(mask);
    EXPECT_EQ(mask->format, OIIO::TypeDesc::UINT8) << image_summary(mask);
    ASSERT_EQ(rainy->pixels.size(), clean->pixels.size());
    ASSERT_EQ(rainy->pixels.size(), mask->pixels.size());

    // clean == the (cropped and resized) input.
    const auto input = read_image(cwd / source, &why);
    ASSERT_TRUE(input) << source << ": " << why;
    if (size) {
      EXPECT_EQ(cv::Size(width, height), *size);
    } else {
      EXPECT_EQ(width, input->width);
      EXPECT_EQ(height, input->height);
    }
    const cv::Mat want = expected_clean(input->pixels, size);
    ASSERT_EQ(want.size(), clean->pixels.size());
    EXPECT_EQ(cv::norm(want, clean->pixels, cv::NORM_INF), 0.0) << "clean differs from the (resized) input";

    // Mask only 0/255; rainy == clean outside it, and differs somewhere inside.
    const long ones = cv::countNonZero(mask->pixels == 255), zeros = cv::countNonZero(mask->pixels == 0);
    EXPECT_EQ(ones + zeros, static_cast<long>(width) * height) << "mask values other than 0 and 255";
    // Landscape frames always show drops. A tall portrait frame at native size can legitimately
    // come out empty: with the default (Cityscapes-width) field of view its bottom rows look
    // along the tilted glass, where uniformly placed drops are sub-pixel.
    if (width >= height) {
      EXPECT_GT(ones, 0) << "empty mask";
    }
    cv::Mat diff;
    cv::absdiff(rainy->pixels, clean->pixels, diff);
    cv::Mat diff_any;
    cv::transform(diff, diff_any, cv::Matx13f(1, 1, 1));  // sum of channel differences
    const cv::Mat outside = mask->pixels == 0, inside = mask->pixels == 255;
    EXPECT_EQ(cv::countNonZero(diff_any & outside), 0) << "rainy differs from clean outside the mask";
    if (ones > 0) {
      EXPECT_GT(cv::countNonZero(diff_any & inside), 0) << "rainy equals clean everywhere inside the mask";
    }

    // coverage = fraction of 255 pixels.
    const double fraction = static_cast<double>(ones) / (static_cast<double>(width) * height);
    EXPECT_NEAR(r.at("coverage").get<double>(), fraction, 1e-12);
  }
  // No stray samples beyond those in the manifest.
  const auto files = sample_files(out);
  EXPECT_EQ(std::set<std::string>(files.begin(), files.end()), sample_names);
}

TEST(RenderDataset, ContractHoldsResized) {
  TempDir tmp;
  make_inputs(tmp.path());
  const auto r = run_render({"-i", "in", "--out", "out", "--variants", "2", "--size", "256x128", "--seed", "11",
                             "-j", "2", "-q"},
                            tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  check_dataset(tmp.path(), tmp / "out", cv::Size(256, 128), 11, 2);
}

TEST(RenderDataset, ContractHoldsNativeSizeAndUpscaled) {
  TempDir tmp;
  make_inputs(tmp.path());
  auto r = run_render({"-i", "in", "--out", "native", "--variants", "2", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  check_dataset(tmp.path(), tmp / "native", std::nullopt, 0, 2);
  // 800x300 upscales all but the first input (bilinear) after cropping to 8:3.
  r = run_render({"-i", "in", "--out", "up", "--size", "800x300", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  check_dataset(tmp.path(), tmp / "up", cv::Size(800, 300), 0, 1);
}

TEST(RenderDataset, ByteIdenticalAcrossThreadCounts) {
  TempDir tmp;
  make_inputs(tmp.path());
  for (const std::string size : {"256x128", "native"}) {
    SCOPED_TRACE("--size " + size);
    std::vector<std::string> base = {"-i", "in", "--variants", "2", "--seed", "5", "-q"};
    if (size != "native") base.insert(base.end(), {"--size", size});
    auto one = base, two = base;
    one.insert(one.end(), {"-j", "1", "--out", "j1-" + size});
    two.insert(two.end(), {"-j", "2", "--out", "j2-" + size});
    const auto r1 = run_render(one, tmp.path());
    ASSERT_EQ(r1.code, 0) << r1.describe();
    const auto r2 = run_render(two, tmp.path());
    ASSERT_EQ(r2.code, 0) << r2.describe();
    const auto a = snapshot(tmp / ("j1-" + size)), b = snapshot(tmp / ("j2-" + size));
    ASSERT_EQ(a.size(), 3u * 8 + 1) << "8 samples x 3 images + manifest expected: " << ::testing::PrintToString(list_files(tmp / ("j1-" + size)));
    ASSERT_EQ(manifest_lines(tmp / ("j1-" + size)).size(), 8u);
    std::vector<std::string> names_a, names_b;
    for (const auto& [k, v] : a) names_a.push_back(k);
    for (const auto& [k, v] : b) names_b.push_back(k);
    ASSERT_EQ(names_a, names_b);
    for (const auto& [name, bytes] : a) EXPECT_TRUE(bytes == b.at(name)) << name << " differs between -j 1 and -j 2";
  }
}

TEST(RenderDataset, SeedChangesRainyButNotClean) {
  TempDir tmp;
  make_inputs(tmp.path());
  const std::vector<std::string> base = {"-i", "in", "--variants", "2", "--size", "256x128", "-j", "2", "-q"};
  auto a = base, b = base;
  a.insert(a.end(), {"--seed", "1", "--out", "seed1"});
  b.insert(b.end(), {"--seed", "2", "--out", "seed2"});
  const auto ra = run_render(a, tmp.path());
  ASSERT_EQ(ra.code, 0) << ra.describe();
  const auto rb = run_render(b, tmp.path());
  ASSERT_EQ(rb.code, 0) << rb.describe();
  const auto records = read_manifest(tmp / "seed1");
  ASSERT_EQ(records.size(), 8u);
  for (const auto& rec : records) {
    const std::string id = rec.at("id");
    const std::string rainy = "rainy/" + id + ".png", clean = "clean/" + id + ".png", mask = "mask/" + id + ".png";
    ASSERT_TRUE(fs::exists(tmp / "seed2" / rainy)) << id;
    EXPECT_FALSE(read_file(tmp / "seed1" / rainy) == read_file(tmp / "seed2" / rainy)) << id << ": seed had no effect on rainy";
    EXPECT_FALSE(read_file(tmp / "seed1" / mask) == read_file(tmp / "seed2" / mask)) << id << ": seed had no effect on mask";
    EXPECT_TRUE(read_file(tmp / "seed1" / clean) == read_file(tmp / "seed2" / clean)) << id << ": clean depends on the seed";
  }
  // The two variants of one input also differ from each other.
  EXPECT_FALSE(read_file(tmp / "seed1/rainy/a_street_v00.png") == read_file(tmp / "seed1/rainy/a_street_v01.png"));
}

// The variants of one input share its clean image: written once, the other variants get a
// copy of the same bytes, which decode to what a one-variant run writes.
TEST(RenderDataset, VariantsOfAnInputShareTheCleanImagesBytes) {
  TempDir tmp;
  make_inputs(tmp.path());
  auto r = run_render({"-i", "in", "--out", "three", "--variants", "3", "--size", "256x128", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  r = run_render({"-i", "in", "--out", "one", "--size", "256x128", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  for (const std::string& stem : kInputStems) {
    SCOPED_TRACE(stem);
    const std::string first = read_file(tmp / "three" / "clean" / (stem + "_v00.png"));
    ASSERT_FALSE(first.empty());
    for (const char* v : {"_v01.png", "_v02.png"}) EXPECT_EQ(read_file(tmp / "three" / "clean" / (stem + v)), first) << v;
    std::string why;
    const auto a = read_image(tmp / "three" / "clean" / (stem + "_v02.png"), &why);
    const auto b = read_image(tmp / "one" / "clean" / (stem + "_v00.png"), &why);
    ASSERT_TRUE(a && b) << why;
    EXPECT_EQ(cv::norm(a->pixels, b->pixels, cv::NORM_INF), 0);
  }
  // No temporary left behind by the copies.
  for (const auto& e : fs::directory_iterator(tmp / "three" / "clean"))
    EXPECT_EQ(e.path().extension(), ".png") << e.path();
}

}  // namespace
}  // namespace clitest
