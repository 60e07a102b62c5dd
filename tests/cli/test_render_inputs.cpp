// End-to-end: where the frames come from (Cityscapes walk with camera intrinsics, list files,
// the built-in demo) and the informational options.
#include <algorithm>
#include <map>
#include <set>

#include "cli_test_util.h"

namespace clitest {
namespace {

fs::path cityscapes_root() { return fs::path(RAINDROP_SHARED_DATA) / "cityscapes-mini"; }

#define REQUIRE_CITYSCAPES()                                                                                \
  do {                                                                                                      \
    if (!fs::is_directory(cityscapes_root() / "leftImg8bit"))                                               \
      GTEST_SKIP() << "real-image folder " << cityscapes_root()                                             \
                   << " is absent (RAINDROP_SHARED_DATA); the Cityscapes walk is tested only where it exists"; \
  } while (0)

TEST(RenderCityscapes, ValSplitUsesCameraJsonIntrinsics) {
  REQUIRE_CITYSCAPES();
  TempDir tmp;
  const auto r = run_render({"--cityscapes", cityscapes_root().string(), "--split", "val", "--size", "512x256", "--out",
                             "out", "-j", "2", "-q"},
                            tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto records = read_manifest(tmp / "out");
  ASSERT_EQ(records.size(), 2u) << "the mini set has two val frames";
  std::set<std::string> ids;
  for (const auto& rec : records) {
    const std::string id = rec.at("id");
    SCOPED_TRACE(id);
    ids.insert(id);
    EXPECT_EQ(rec.at("split"), "val");
    EXPECT_EQ(rec.at("width"), 512);
    EXPECT_EQ(rec.at("height"), 256);
    const json& cam = rec.at("camera");
    EXPECT_EQ(cam.at("origin"), "cityscapes-json");
    // aachen intrinsics at 2048x1024: fx 2262.52, fy 2265.30..., u0 1096.98, v0 513.137; scaled by
    // 1/4 with pixel centres at integers: c' = (c + 0.5) * s - 0.5.
    EXPECT_NEAR(cam.at("fx").get<double>(), 2262.52 / 4, 1e-6);
    EXPECT_NEAR(cam.at("fy").get<double>(), 2265.3017905988554 / 4, 1e-6);
    EXPECT_NEAR(cam.at("cx").get<double>(), (1096.98 + 0.5) * 0.25 - 0.5, 1e-6);
    EXPECT_NEAR(cam.at("cy").get<double>(), (513.137 + 0.5) * 0.25 - 0.5, 1e-6);
    const double coverage = rec.at("coverage");
    EXPECT_GT(coverage, 0.02);
    EXPECT_LT(coverage, 0.5);
    const fs::path source = rec.at("source").get<std::string>();
    EXPECT_TRUE(fs::exists(source)) << source;
    EXPECT_NE(source.string().find("leftImg8bit/val/aachen"), std::string::npos) << source;
    for (const char* kind : {"rainy", "clean", "mask"}) {
      std::string why;
      const auto img = read_image(tmp / "out" / rec.at(kind).get<std::string>(), &why);
      ASSERT_TRUE(img) << kind << ": " << why;
      EXPECT_EQ(img->width, 512);
      EXPECT_EQ(img->height, 256);
    }
  }
  EXPECT_EQ(ids, (std::set<std::string>{"aachen_000006_000019_v00", "aachen_000007_000019_v00"}));
}

TEST(RenderCityscapes, SplitAllFindsEveryFrame) {
  REQUIRE_CITYSCAPES();
  TempDir tmp;
  const auto r = run_render({"--cityscapes", cityscapes_root().string(), "--split", "all", "--size", "128x64", "--out",
                             "out", "-j", "2", "-q"},
                            tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto records = read_manifest(tmp / "out");
  EXPECT_EQ(records.size(), 8u);
  std::map<std::string, int> per_split;
  for (const auto& rec : records) {
    ++per_split[rec.at("split").get<std::string>()];
    EXPECT_EQ(rec.at("camera").at("origin"), "cityscapes-json");
  }
  EXPECT_EQ(per_split, (std::map<std::string, int>{{"train", 6}, {"val", 2}}));
  EXPECT_EQ(sample_files(tmp / "out").size(), 3u * 8);
}

// The tests above need the real mini set; these run everywhere, on a generated folder in the
// Cityscapes layout (leftImg8bit/<split>/<city>/<city>_<seq>_000019_leftImg8bit.png, and
// camera/<split>/<city>/<city>_<seq>_000019_camera.json) with made-up intrinsics, different
// for every frame, so that each frame must get its own file's.
struct GeneratedFrame {
  std::string split, city;
  int seq;
  bool has_camera;
  double fx, fy, u0, v0;  // at the generated 256x128
  std::string stem() const {
    char s[64];
    std::snprintf(s, sizeof s, "%s_%06d_000019", city.c_str(), seq);
    return s;
  }
};

const std::vector<GeneratedFrame> kGeneratedFrames = {
    {"train", "bochum", 3, true, 301.5, 302.25, 131.75, 62.5},
    {"train", "bochum", 11, true, 288.0, 289.125, 124.5, 66.25},
    {"train", "zurich", 0, false, 0, 0, 0, 0},  // no camera file: the default camera
    {"val", "lindau", 0, true, 279.75, 281.5, 120.25, 60.75},
    {"val", "lindau", 1, true, 310.25, 309.0, 135.5, 64.0},
    {"test", "berlin", 7, true, 295.0, 296.5, 126.0, 63.5},
};

void make_generated_cityscapes(const fs::path& root) {
  int seed = 0;
  for (const auto& f : kGeneratedFrames) {
    write_image(root / "leftImg8bit" / f.split / f.city / (f.stem() + "_leftImg8bit.png"), make_background(256, 128, seed++));
    if (!f.has_camera) continue;
    const json cam = {{"extrinsic", {{"baseline", 0.21}, {"pitch", 0.04}, {"roll", 0.0}, {"x", 1.7}, {"y", 0.1}, {"yaw", -0.02}, {"z", 1.2}}},
                      {"intrinsic", {{"fx", f.fx}, {"fy", f.fy}, {"u0", f.u0}, {"v0", f.v0}}}};
    const fs::path file = root / "camera" / f.split / f.city / (f.stem() + "_camera.json");
    fs::create_directories(file.parent_path());
    write_file(file, cam.dump(4));
  }
}

// Checks each record's split, source and camera against the generated frame it names;
// rendered at 128x64, half the generated size.
void expect_generated_records(const std::vector<json>& records) {
  for (const auto& rec : records) {
    const std::string id = rec.at("id");
    SCOPED_TRACE(id);
    const auto f = std::find_if(kGeneratedFrames.begin(), kGeneratedFrames.end(),
                                [&](const GeneratedFrame& g) { return g.stem() + "_v00" == id; });
    ASSERT_NE(f, kGeneratedFrames.end()) << "no generated frame has this id";
    EXPECT_EQ(rec.at("split"), f->split);
    const std::string source = rec.at("source");
    EXPECT_NE(source.find("leftImg8bit/" + f->split + "/" + f->city + "/" + f->stem() + "_leftImg8bit.png"),
              std::string::npos)
        << source;
    const json& cam = rec.at("camera");
    if (!f->has_camera) {
      EXPECT_EQ(cam.at("origin"), "default");
      continue;
    }
    EXPECT_EQ(cam.at("origin"), "cityscapes-json");
    // Scaled by 1/2 with pixel centres at integers: c' = (c + 0.5) * s - 0.5.
    EXPECT_NEAR(cam.at("fx").get<double>(), f->fx / 2, 1e-9);
    EXPECT_NEAR(cam.at("fy").get<double>(), f->fy / 2, 1e-9);
    EXPECT_NEAR(cam.at("cx").get<double>(), (f->u0 + 0.5) * 0.5 - 0.5, 1e-9);
    EXPECT_NEAR(cam.at("cy").get<double>(), (f->v0 + 0.5) * 0.5 - 0.5, 1e-9);
  }
}

// The generated folder in <tmp>/cs, its `split` rendered at 128x64 into <tmp>/out: the records.
std::vector<json> render_generated_cityscapes(const TempDir& tmp, const std::string& split) {
  make_generated_cityscapes(tmp / "cs");
  const auto r = run_render({"--cityscapes", "cs", "--split", split, "--size", "128x64", "--out", "out", "-j", "2", "-q"},
                            tmp.path());
  EXPECT_EQ(r.code, 0) << r.describe();
  return read_manifest(tmp / "out");
}

TEST(RenderCityscapes, GeneratedValSplitUsesEachFramesCameraJson) {
  TempDir tmp;
  const auto records = render_generated_cityscapes(tmp, "val");
  ASSERT_EQ(records.size(), 2u);
  expect_generated_records(records);
  for (const auto& rec : records) {
    for (const char* kind : {"rainy", "clean", "mask"}) {
      const auto img = read_image(tmp / "out" / rec.at(kind).get<std::string>());
      ASSERT_TRUE(img) << kind;
      EXPECT_EQ(img->width, 128);
      EXPECT_EQ(img->height, 64);
    }
  }
}

TEST(RenderCityscapes, GeneratedSplitAllFindsEveryFrame) {
  TempDir tmp;
  const auto records = render_generated_cityscapes(tmp, "all");
  EXPECT_EQ(records.size(), kGeneratedFrames.size());
  expect_generated_records(records);
  std::map<std::string, int> per_split;
  for (const auto& rec : records) ++per_split[rec.at("split").get<std::string>()];
  EXPECT_EQ(per_split, (std::map<std::string, int>{{"test", 1}, {"train", 3}, {"val", 2}}));
}

TEST(RenderCityscapes, BadCameraJsonIsAnErrorNamingTheFile) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {R"({"extrinsic": {}})", "not a Cityscapes camera file"},
      {R"({"intrinsic": {"fx": 300, "fy": 300, "u0": 128}})", "not a Cityscapes camera file"},
      {R"({"intrinsic": {"fx": "300", "fy": 300, "u0": 128, "v0": 64}})", "not a Cityscapes camera file"},
      {R"({"intrinsic": {"fx": -300, "fy": 300, "u0": 128, "v0": 64}})", "focal lengths must be positive"},
      {"{not json", "not a Cityscapes camera file"}};
  for (const auto& [text, why] : bad) {
    SCOPED_TRACE(text);
    TempDir tmp;
    make_generated_cityscapes(tmp / "cs");
    write_file(tmp / "cs" / "camera" / "val" / "lindau" / "lindau_000001_000019_camera.json", text);
    const auto r = run_render({"--cityscapes", "cs", "--split", "val", "--out", "out", "-q"}, tmp.path());
    expect_clean_failure(r, tmp / "out", "lindau_000001_000019_camera.json");
    const auto lines = r.message_lines();
    ASSERT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_NE(lines[0].find(why), std::string::npos) << lines[0];
  }
}

TEST(RenderCityscapes, MissingLayoutIsAnError) {
  TempDir tmp;
  fs::create_directories(tmp / "not-cityscapes" / "images");
  const auto r = run_render({"--cityscapes", "not-cityscapes", "--out", "out"}, tmp.path());
  expect_clean_failure(r, tmp / "out", "not-cityscapes");
}

// Into a folder the user names, the demo only when asked: a forgotten input is an error there
// (it used to write the demo's backgrounds and samples into that folder).
TEST(RenderDemo, AnOutputFolderWithoutAnInputIsAnError) {
  TempDir tmp;
  fs::create_directories(tmp / "mine");
  const auto r = run_render({"--out", "mine", "-j", "2"}, tmp.path());
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("no input"), std::string::npos) << r.describe();
  EXPECT_TRUE(fs::is_empty(tmp / "mine"));
}

// An option given an empty value read as not given: --merge-shards "" rendered the demo into
// ./out, --shard "" rendered every shard. --sheet-rows without a sheet was ignored.
TEST(RenderDemo, AnEmptyValueOrASheetsRowsWithoutASheetAreErrors) {
  TempDir tmp;
  write_image(tmp / "in" / "a.png", make_background(96, 64, 0));
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--merge-shards", ""}, "--merge-shards needs a value"},
      {{"-i", "in", "-o", "o", "--shard", ""}, "--shard needs a value"},
      {{"-i", "in", "-o", "o", "--contact-sheet", ""}, "--contact-sheet needs a value"},
      {{"-i", "in", "-o", "o", "--sheet-rows", "3"}, "give --contact-sheet"},
  };
  for (const auto& [args, needle] : cases) {
    const auto r = run_render(args, tmp.path());
    EXPECT_NE(r.code, 0) << r.describe();
    EXPECT_EQ(r.message_lines().size(), 1u) << r.describe();
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.describe();
  }
  EXPECT_FALSE(fs::exists(tmp / "out"));
  EXPECT_FALSE(fs::exists(tmp / "o" / "manifest.jsonl"));
  // The demo's own sheet takes --sheet-rows.
  const auto demo = run_render({"--size", "64x32", "--sheet-rows", "2", "-q"}, tmp.path());
  EXPECT_EQ(demo.code, 0) << demo.describe();
  EXPECT_TRUE(fs::exists(tmp / "out" / "demo" / "contact_sheet.png"));
}

TEST(RenderDemo, NoInputRendersTheDemoAndAContactSheet) {
  TempDir tmp;
  const auto r = run_render({"--demo", "--out", "demo", "-j", "2"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  std::string why;
  const auto sheet = read_image(tmp / "demo" / "contact_sheet.png", &why);
  ASSERT_TRUE(sheet) << why;
  EXPECT_GT(sheet->width, sheet->height);
  EXPECT_GE(sheet->channels, 3);
  const auto records = read_manifest(tmp / "demo");
  std::set<std::string> ids;
  for (const auto& rec : records) ids.insert(rec.at("id").get<std::string>());
  EXPECT_EQ(ids, (std::set<std::string>{"checkerboard_v00", "street_v00"}));
  for (const auto& id : ids) {
    for (const char* kind : {"rainy", "clean", "mask"}) {
      EXPECT_TRUE(read_image(tmp / "demo" / kind / (id + ".png"))) << kind << "/" << id;
    }
  }
  // The demo's own backgrounds are what the clean images hold.
  const auto bg = read_image(tmp / "demo" / "backgrounds" / "street.png");
  const auto clean = read_image(tmp / "demo" / "clean" / "street_v00.png");
  ASSERT_TRUE(bg && clean);
  EXPECT_EQ(cv::norm(bg->pixels, clean->pixels, cv::NORM_INF), 0.0);
  const cv::Mat drawn = raindrop::demo_street(bg->width, bg->height);
  EXPECT_EQ(cv::norm(bg->pixels, drawn, cv::NORM_INF), 0.0);
}

TEST(RenderInfo, HelpListScenesVersion) {
  TempDir tmp;
  const auto help = run_render({"--help"}, tmp.path());
  EXPECT_EQ(help.code, 0) << help.describe();
  EXPECT_NE(help.out.find("--cityscapes"), std::string::npos) << help.describe();
  EXPECT_NE(help.out.find("--keep-going"), std::string::npos) << help.describe();

  const auto scenes = run_render({"--list-scenes"}, tmp.path());
  EXPECT_EQ(scenes.code, 0) << scenes.describe();
  const auto names = split_lines(scenes.out);
  EXPECT_NE(std::find(names.begin(), names.end(), "paper"), names.end()) << scenes.describe();

  const auto version = run_render({"--version"}, tmp.path());
  EXPECT_EQ(version.code, 0) << version.describe();
  EXPECT_NE(version.out.find("raindrop-render "), std::string::npos) << version.describe();

  // None of them renders anything.
  EXPECT_FALSE(fs::exists(tmp / "out"));
  EXPECT_EQ(list_files(tmp.path()).size(), list_files(tmp / "_logs").size());
}

// Every preset that --list-scenes names must load, and the presets that --help offers in the
// --scene description, "Preset (a, b, c) or JSON scene file", must be the listed ones.
TEST(RenderInfo, PresetsInHelpAndListAgreeAndLoad) {
  TempDir tmp;
  const auto scenes = run_render({"--list-scenes"}, tmp.path());
  ASSERT_EQ(scenes.code, 0);
  const auto names = split_lines(scenes.out);
  ASSERT_FALSE(names.empty());
  for (const auto& name : names) {
    const auto r = run_render({"--scene", name, "--print-scene"}, tmp.path());
    EXPECT_EQ(r.code, 0) << r.describe();
    json parsed;
    ASSERT_NO_THROW(parsed = json::parse(r.out)) << r.describe();
    EXPECT_EQ(parsed.at("name"), name);
  }
  const auto help = run_render({"--help"}, tmp.path());
  ASSERT_EQ(help.code, 0);
  const auto at = help.out.find("Preset (");
  ASSERT_NE(at, std::string::npos) << help.out;
  const auto end = help.out.find(')', at);
  ASSERT_NE(end, std::string::npos);
  std::set<std::string> offered;
  std::istringstream list(help.out.substr(at + 8, end - at - 8));
  std::string item;
  while (std::getline(list, item, ',')) {
    item.erase(0, item.find_first_not_of(' '));
    offered.insert(item);
  }
  EXPECT_EQ(offered, std::set<std::string>(names.begin(), names.end()))
      << "--help's --scene text offers presets that --list-scenes does not have (or misses some)";
}

// A scene file without a "name" is named after its file, however the path is written: a bare
// file name ("all.json") was named "'all", from the quoted path of the error messages. Its blur,
// given no method, is the antialiased disk that docs/SCENES.md names as the default (it was the
// binary disk).
TEST(RenderInfo, ASceneFileIsNamedAfterItsFileAndItsBlurDefaultsToTheAntialiasedDisk) {
  TempDir tmp;
  write_file(tmp / "sc" / "all.json", R"({"drop_count": 5, "effects": {"blur": {}}})");
  for (const auto& [dir, path] : {std::pair<std::string, std::string>{"sc", "all.json"}, {"sc", "./all.json"}, {"", "sc/all.json"}}) {
    SCOPED_TRACE(path);
    const auto r = run_render({"--scene", path, "--print-scene"}, tmp / dir);
    ASSERT_EQ(r.code, 0) << r.describe();
    json parsed;
    ASSERT_NO_THROW(parsed = json::parse(r.out)) << r.describe();
    EXPECT_EQ(parsed.at("name"), "all");
    EXPECT_EQ(parsed.at("effects").at("blur").at("method"), "disk-aa");
  }
}

// An output folder inside the input folder: a second run must not take the first run's
// rainy/clean/mask images as inputs (it rendered them, and failed on the grey masks).
TEST(RenderFolder, OutputFolderInsideTheInputIsNotAnInput) {
  TempDir tmp;
  write_image(tmp / "rin" / "a.png", make_background(96, 64, 0));
  write_image(tmp / "rin" / "sub" / "b.png", make_background(96, 64, 1));
  for (int run = 0; run < 2; ++run) {
    SCOPED_TRACE(run);
    const auto r = run_render({"-i", "rin", "-o", "rin/out", "-j", "2", "-q"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto counts = parse_counts(r.err);
    ASSERT_TRUE(counts) << r.describe();
    EXPECT_EQ(counts->rendered, run == 0 ? 2 : 0) << r.describe();
    EXPECT_EQ(counts->skipped, run == 0 ? 0 : 2) << r.describe();
    EXPECT_EQ(manifest_lines(tmp / "rin" / "out").size(), 2u);
  }
  // Also when the two are spelled differently.
  const auto r = run_render({"-i", "./rin/", "-o", "rin/sub/../out", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(manifest_lines(tmp / "rin" / "out").size(), 2u) << r.describe();
}

// The output folder is the input folder, or holds it: every image under the input is still an
// input (skipping the output folder used to skip all their subfolders, silently), and a second
// run into the input folder itself does not take its rainy/clean/mask images as inputs.
TEST(RenderFolder, OutputFolderThatIsOrHoldsTheInputSkipsNoSubfolder) {
  TempDir tmp;
  for (const char* root : {"r", "p"}) {
    write_image(tmp / root / "imgs" / "a.png", make_background(96, 64, 0));
    write_image(tmp / root / "imgs" / "sub" / "b.png", make_background(96, 64, 1));
  }
  for (const auto& [in, out] : {std::pair{"r/imgs", "r/imgs"}, std::pair{"r/imgs", "r/imgs"}, std::pair{"p/imgs", "p"}}) {
    SCOPED_TRACE(out);
    const auto r = run_render({"-i", in, "-o", out, "-j", "2", "-q"}, tmp.path());
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto counts = parse_counts(r.err);
    ASSERT_TRUE(counts) << r.describe();
    EXPECT_EQ(counts->rendered + counts->skipped, 2) << r.describe();
    EXPECT_EQ(manifest_lines(tmp / out).size(), 2u);
  }
}

// The contact sheet is checked before the render: it may not replace an input or a rendered
// sample, and a destination it cannot be written to stops the run before any work.
TEST(RenderFolder, TheContactSheetNeitherReplacesAFileNorFailsLate) {
  TempDir tmp;
  write_image(tmp / "in" / "a.png", make_background(96, 64, 0));
  const std::string before = read_file(tmp / "in" / "a.png");
  write_image(tmp / "in" / "b.png", make_background(96, 64, 1));
  for (const char* sheet : {"in/a.png", "./in/../in/a.png", "in/b.png", "o/rainy/a_v00.png", "o/mask/x.png", "nodir/s.png", "s.jsonl"}) {
    SCOPED_TRACE(sheet);
    // --limit 1: in/b.png is not rendered, and still the user's.
    const auto r = run_render({"-i", "in", "-o", "o", "--limit", "1", "--contact-sheet", sheet, "-q"}, tmp.path());
    EXPECT_NE(r.code, 0) << r.describe();
    EXPECT_EQ(r.message_lines().size(), 1u) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "o" / "manifest.jsonl")) << "refused only after rendering";
  }
  EXPECT_EQ(read_file(tmp / "in" / "a.png"), before);
  const auto ok = run_render({"-i", "in", "-o", "o/", "--contact-sheet", "o/sheet.png", "-q"}, tmp.path());
  EXPECT_EQ(ok.code, 0) << ok.describe();
  EXPECT_TRUE(fs::exists(tmp / "o" / "sheet.png"));
  // An input inside a folder the run writes into would be rendered again on every re-run.
  const auto loop = run_render({"-i", "o/rainy", "-o", "o", "-q"}, tmp.path());
  EXPECT_EQ(loop.code, 1) << loop.describe();
  EXPECT_EQ(loop.message_lines().size(), 1u) << loop.describe();
}

// A resumed run's sheet shows the same first samples as a fresh run's, those done before read
// back: it wrote no sheet at all when every sample was done (and said it had), and a sheet of
// only the samples it rendered when some were.
TEST(RenderFolder, AResumedRunWritesTheSheetAFreshRunWrites) {
  TempDir tmp;
  for (int i = 0; i < 3; ++i) write_image(tmp / "in" / ("f" + std::to_string(i) + ".png"), make_background(96, 64, i));
  const std::vector<std::string> args = {"-i", "in", "-o", "o", "--variants", "2", "--sheet-rows", "3",
                                         "--contact-sheet", "sheet.png", "-q"};
  auto r = run_render(args, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const std::string fresh = read_file(tmp / "sheet.png");
  ASSERT_FALSE(fresh.empty());
  fs::remove(tmp / "sheet.png");
  r = run_render(args, tmp.path());  // every sample done
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(read_file(tmp / "sheet.png"), fresh) << r.describe();
  fs::remove(tmp / "sheet.png");
  fs::remove(tmp / "o" / "mask" / "f0_v01.png");  // one sample to render again, in the sheet's rows
  r = run_render(args, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto counts = parse_counts(r.err);
  ASSERT_TRUE(counts) << r.describe();
  EXPECT_EQ(counts->rendered, 1) << r.describe();
  EXPECT_EQ(read_file(tmp / "sheet.png"), fresh);
}

// The demo renders into out/demo, unless an output folder is named, even the default's own name.
TEST(RenderFolder, TheDemoWritesWhereItIsTold) {
  TempDir tmp;
  const auto r = run_render({"--demo", "-o", "out/render", "--size", "64x32", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_TRUE(fs::exists(tmp / "out" / "render" / "manifest.jsonl"));
  EXPECT_FALSE(fs::exists(tmp / "out" / "demo"));
}

// A folder of symbolic links to images elsewhere (a common way to pick a subset): each is
// named after its link, not after where it points. Resolving the link made names such as
// "..-..-data-a_v00.png", hidden files that raindrop-remove's folder mode then skips.
TEST(RenderFolder, SymlinkedImagesAreNamedAfterTheirLinks) {
  TempDir tmp;
  write_image(tmp / "elsewhere" / "a.png", make_background(96, 64, 0));
  fs::create_directories(tmp / "picked");
  fs::create_symlink(fs::absolute(tmp / "elsewhere" / "a.png"), tmp / "picked" / "first.png");
  const auto r = run_render({"-i", "picked", "-o", "out", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(list_files(tmp / "out" / "rainy"), std::vector<std::string>{"first_v00.png"});
}

TEST(RenderListFile, RendersExactlyTheListedImages) {
  TempDir tmp;
  write_image(tmp / "imgs" / "sub" / "alpha.png", make_background(160, 80, 0));
  write_image(tmp / "imgs" / "beta.png", make_background(150, 100, 1));
  write_image(tmp / "imgs" / "gamma.png", make_background(120, 90, 2));  // in the folder, not listed
  const fs::path beta_abs = fs::absolute(tmp / "imgs" / "beta.png");
  write_file(tmp / "imgs" / "frames.txt",
             "# two frames for the test\n"
             "sub/alpha.png\n"
             "\n"
             "   \n" +
                 beta_abs.string() + "\n"
             "# gamma.png is deliberately not listed\n");
  const auto r = run_render({"-i", "imgs/frames.txt", "--out", "out", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto records = read_manifest(tmp / "out");
  std::map<std::string, std::string> source_of;
  for (const auto& rec : records) source_of[rec.at("id")] = rec.at("source");
  ASSERT_EQ(source_of.size(), 2u) << ::testing::PrintToString(source_of);
  ASSERT_TRUE(source_of.count("alpha_v00") && source_of.count("beta_v00")) << ::testing::PrintToString(source_of);
  // Relative entries are relative to the list file's folder.
  EXPECT_TRUE(fs::equivalent(tmp / source_of["alpha_v00"], tmp / "imgs" / "sub" / "alpha.png"));
  EXPECT_EQ(source_of["beta_v00"], beta_abs.string());
  EXPECT_EQ(sample_files(tmp / "out").size(), 6u);
  for (const auto& [id, name] : std::map<std::string, std::string>{{"alpha_v00", "sub/alpha.png"}, {"beta_v00", "beta.png"}}) {
    const auto input = read_image(tmp / "imgs" / name);
    const auto clean = read_image(tmp / "out" / "clean" / (id + ".png"));
    ASSERT_TRUE(input && clean) << id;
    EXPECT_EQ(cv::norm(input->pixels, clean->pixels, cv::NORM_INF), 0.0) << id;
  }
}

TEST(RenderListFile, ListedMissingImageIsAnError) {
  TempDir tmp;
  write_image(tmp / "imgs" / "here.png", make_background(96, 64, 0));
  write_file(tmp / "imgs" / "frames.txt", "here.png\nmissing.png\n");
  const auto r = run_render({"-i", "imgs/frames.txt", "--out", "out", "-j", "2"}, tmp.path());
  expect_clean_failure(r, tmp / "out", "missing.png");
}

// Two inputs that would get the same sample id (same file stem from a list) are refused
// before anything is rendered.
TEST(RenderListFile, DuplicateIdsAreRefused) {
  TempDir tmp;
  write_image(tmp / "imgs" / "a" / "frame.png", make_background(96, 64, 0));
  write_image(tmp / "imgs" / "b" / "frame.png", make_background(96, 64, 1));
  write_file(tmp / "imgs" / "frames.txt", "a/frame.png\nb/frame.png\n");
  const auto r = run_render({"-i", "imgs/frames.txt", "--out", "out", "-j", "2"}, tmp.path());
  expect_clean_failure(r, tmp / "out", "frame");
}

// --limit N renders the first N inputs of the (sorted) folder walk.
TEST(RenderListFile, LimitTakesTheFirstInputs) {
  TempDir tmp;
  for (const char* name : {"d.png", "b.png", "a.png", "c.png"})
    write_image(tmp / "in" / name, make_background(96, 64, name[0]));
  const auto r = run_render({"-i", "in", "--out", "out", "--limit", "2", "-j", "2", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  std::vector<std::string> ids;
  for (const auto& rec : read_manifest(tmp / "out")) ids.push_back(rec.at("id"));
  EXPECT_EQ(ids, (std::vector<std::string>{"a_v00", "b_v00"}));
  EXPECT_EQ(sample_files(tmp / "out").size(), 6u);
}

}  // namespace
}  // namespace clitest

namespace clitest {
namespace {

// Ids keep non-ASCII letters: "café" and "cafè" were both "caf__", and the run was refused.
// A name that is not UTF-8 still gives an id that is valid JSON and a file name (it stopped the
// run after its images were written: the manifest's source path could not be JSON).
TEST(RenderIds, NonAsciiNamesKeepTheirLetters) {
  TempDir tmp;
  const std::string not_utf8 = std::string("bad") + static_cast<char>(0xFF) + static_cast<char>(0xC3) + "x";
  for (const std::string& name : std::vector<std::string>{"café", "cafè", "東京 1", not_utf8})
    write_image(tmp / "in" / (name + ".png"), make_background(64, 48, static_cast<int>(name.size())));
  const auto r = run_render({"-i", "in", "--out", "out", "-q"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  std::set<std::string> ids;
  for (const auto& rec : read_manifest(tmp / "out")) ids.insert(rec.at("id").get<std::string>());
  EXPECT_EQ(ids, (std::set<std::string>{"café_v00", "cafè_v00", "東京_1_v00", "bad__x_v00"}));
  for (const auto& id : ids) EXPECT_TRUE(fs::exists(tmp / "out" / "rainy" / (id + ".png"))) << id;
  bool replaced = false;
  for (const auto& rec : read_manifest(tmp / "out"))
    replaced = replaced || rec.at("source").get<std::string>() == "in/bad\xEF\xBF\xBD\xEF\xBF\xBDx.png";
  EXPECT_TRUE(replaced) << "the source path's stray bytes as U+FFFD";
}

}  // namespace
}  // namespace clitest

namespace clitest {
namespace {

// An installed tree (cmake --install) holds raindrop-render, as the cluster examples of the
// README run it, and its plugin in lib/raindrop: a TIFF in, a data set out, the same bytes as
// the build tree's program writes.
TEST(RenderInstall, InstalledProgramRendersFromATiff) {
  TempDir tmp;
  const RunResult install = RunResult{testsupport::run_captured(
      "cmake", {"--install", render_bin().parent_path().string(), "--prefix", (tmp / "inst").string()}, tmp.path())};
  ASSERT_EQ(install.code, 0) << install.describe();
  const fs::path installed = tmp / "inst" / "bin" / "raindrop-render";
  ASSERT_TRUE(fs::exists(installed));
  write_image(tmp / "in" / "street.tif", make_background(128, 64, 3));
  const std::vector<std::string> args = {"-i", "in", "--seed", "4", "-j", "1", "-q", "--out"};
  auto with_out = [&](const std::string& out) {
    std::vector<std::string> a = args;
    a.push_back(out);
    return a;
  };
  const RunResult r = RunResult{testsupport::run_captured(installed, with_out("from-install"), tmp.path())};
  ASSERT_EQ(r.code, 0) << r.describe();
  ASSERT_EQ(run_render(with_out("from-build"), tmp.path()).code, 0);
  for (const char* f : {"rainy/street_v00.png", "clean/street_v00.png", "mask/street_v00.png"}) {
    ASSERT_TRUE(fs::exists(tmp / "from-install" / f)) << f;
    EXPECT_EQ(read_file(tmp / "from-install" / f), read_file(tmp / "from-build" / f)) << f;
  }
}

}  // namespace
}  // namespace clitest
