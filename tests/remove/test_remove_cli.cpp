// raindrop-remove end to end: bad inputs (one line, exit code, nothing written), usage
// errors, model discovery, formats kept, folder mode.
#include <chrono>
#include <fstream>
#include <thread>

#include <unistd.h>
#include <zlib.h>

#include <onnxruntime_cxx_api.h>

#include "raindrop/common/image_io.h"
#include "raindrop/remove/int8_precision.h"
#include "remove_test_util.h"

namespace removetest {
namespace {

const std::string kErrorPrefix = "raindrop-remove: error: ";

class RemoveCli : public ::testing::Test {
 protected:
  void SetUp() override { write_image(tmp / "in.png", make_image(61, 43, 1)); }

  // Exit 1, exactly one line on stderr (the error, mentioning `mention`), nothing on stdout,
  // no output, mask or temporary file anywhere in the test folder.
  void expect_clean_failure(const RunResult& r, const std::string& mention, int code = 1) {
    EXPECT_EQ(r.code, code) << r.describe();
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << "expected exactly one error line\n" << r.describe();
    EXPECT_EQ(lines[0].rfind(kErrorPrefix, 0), 0u) << r.describe();
    EXPECT_NE(lines[0].find(mention), std::string::npos) << "should mention '" << mention << "'\n" << r.describe();
    EXPECT_EQ(r.out, "") << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png")) << "partial output left behind";
    EXPECT_FALSE(fs::exists(tmp / "mask.png")) << "mask left behind";
    EXPECT_TRUE(hidden_temporaries(tmp.path()).empty()) << ::testing::PrintToString(hidden_temporaries(tmp.path()));
  }

  RunResult remove(std::vector<std::string> args, const std::vector<std::string>& env = {}) {
    if (std::find(args.begin(), args.end(), "--models") == args.end() && env.empty()) {
      args.push_back("--models");
      args.push_back(smoke_models().string());
    }
    return run_remove(args, tmp.path(), env);
  }

  TempDir tmp;
};

TEST_F(RemoveCli, OneImage) {
  const RunResult r = remove({"in.png", "out.png", "--mask", "mask.png", "--threads", "2"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "") << "a single image prints nothing without --time";
  const auto out = read_image(tmp / "out.png");
  const auto mask = read_image(tmp / "mask.png");
  ASSERT_TRUE(out && mask);
  EXPECT_EQ(out->width, 61);
  EXPECT_EQ(out->height, 43);
  EXPECT_EQ(out->channels, 3);
  EXPECT_EQ(mask->channels, 1);
  EXPECT_EQ(mask->width, 61);
  EXPECT_EQ(cv::countNonZero((mask->pixels != 0) & (mask->pixels != 255)), 0) << "mask is 0/255 only";
  EXPECT_TRUE(hidden_temporaries(tmp.path()).empty());
}

TEST_F(RemoveCli, OutputIntoAnExistingFolder) {
  fs::create_directories(tmp / "results");
  const RunResult r = remove({"in.png", "results"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_TRUE(read_image(tmp / "results" / "in.png"));
}

TEST_F(RemoveCli, TimeAndContactSheet) {
  const RunResult r = remove({"in.png", "out.png", "--time", "--contact-sheet", "sheet.png"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("RDN"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("3RN"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("stages summed"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("ms wall"), std::string::npos) << r.describe();
  const auto sheet = read_image(tmp / "sheet.png");
  ASSERT_TRUE(sheet);
  EXPECT_GT(sheet->width, 3 * 512) << "input | mask | output panels";
}

TEST_F(RemoveCli, HelpVersionAndUsageErrors) {
  RunResult r = remove({"--help"});
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("Exit codes"), std::string::npos) << r.describe();
  EXPECT_NE(r.out.find("--tile-overlap"), std::string::npos) << r.describe();
  r = remove({"--version"});
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.out.find("raindrop-remove "), std::string::npos) << r.describe();
  EXPECT_NE(r.out.find("ONNX Runtime"), std::string::npos) << r.describe();
  for (const std::vector<std::string>& bad :
       {std::vector<std::string>{}, {"in.png"}, {"in.png", "out.png", "--device", "tpu"},
        {"in.png", "out.png", "--graph-opt", "max"}, {"in.png", "out.png", "--tile", "10"},
        {"in.png", "out.png", "--tile", "256", "--tile-overlap", "200"}, {"in.png", "out.png", "--threshold", "2"},
        {"in.png", "out.png", "--dilation", "0"}, {"in.png", "out.png", "--large-drop-growth", "-0.5"},
        {"in.png", "out.png", "--large-drop-growth", "11"}, {"in.png", "out.png", "--no-such-option"},
        {"in.png", "out.png", "--no-large-drops", "--large-drop-growth", "0.3"},
        {"in.png", "out.png", "--large-drop-sharpness", "-1"},
        {"in.png", "out.png", "--no-large-drops", "--large-drop-sharpness", "5"},
        {"in.png", "out.png", "--large-drop-detail", "-0.1"}, {"in.png", "out.png", "--large-drop-detail", "1.5"},
        {"in.png", "out.png", "--no-large-drops", "--large-drop-detail", "0.5"},
        {"in.png", "out.png", "--surround-fill-area", "-1"}, {"in.png", "out.png", "--surround-fill-area", "1.5"},
        {"in.png", "out.png", "--surround-fill-mad", "-2"},
        {"in.png", "out.png", "--no-large-drops", "--large-drop-models", "."}}) {
    r = remove(bad);
    EXPECT_EQ(r.code, 2) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
  }
}

TEST_F(RemoveCli, MissingInput) { expect_clean_failure(remove({"nope.png", "out.png", "--mask", "mask.png"}), "nope.png"); }

TEST_F(RemoveCli, EmptyInput) {
  write_file(tmp / "empty.png", "");
  expect_clean_failure(remove({"empty.png", "out.png", "--mask", "mask.png"}), "empty");
}

// An option given an empty value read as not given: --mask "" wrote no mask, --models "" took
// the default models, --shard "" ran every image. A usage error, as --wet-gate "" is.
TEST_F(RemoveCli, AnOptionGivenAnEmptyValueIsAUsageError) {
  for (const char* name : {"--mask", "--mask-dir", "--contact-sheet", "--shard", "--models", "--model-config",
                           "--large-drop-models"}) {
    SCOPED_TRACE(name);
    const RunResult r = remove({"in.png", "out.png", name, ""});
    EXPECT_EQ(r.code, 2) << r.describe();
    EXPECT_NE(r.err.find(std::string(name) + " needs a value"), std::string::npos) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
  }
}

TEST_F(RemoveCli, TruncatedInput) {
  const std::string bytes = read_file(tmp / "in.png");
  write_file(tmp / "cut.png", bytes.substr(0, bytes.size() / 2));
  expect_clean_failure(remove({"cut.png", "out.png", "--mask", "mask.png"}), "truncated");
}

TEST_F(RemoveCli, NotAnImage) {
  write_file(tmp / "text.png", "hello, I am not a picture\n");
  expect_clean_failure(remove({"text.png", "out.png"}), "text.png");
}

TEST_F(RemoveCli, HugeDeclaredSize) {
  write_file(tmp / "huge.png", png_declaring(100000, 100000));
  expect_clean_failure(remove({"huge.png", "out.png"}), "exceeds");
}

TEST_F(RemoveCli, MissingModelFile) {
  fs::create_directories(tmp / "models");
  fs::copy_file(smoke_models() / "rdn.onnx", tmp / "models" / "rdn.onnx");
  fs::copy_file(smoke_models() / "rrn.onnx", tmp / "models" / "rrn.onnx");
  expect_clean_failure(remove({"in.png", "out.png", "--models", "models"}), "rfn.onnx");
}

TEST_F(RemoveCli, CorruptModelFile) {
  fs::create_directories(tmp / "models");
  for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) fs::copy_file(smoke_models() / f, tmp / "models" / f);
  const std::string bytes = read_file(tmp / "models" / "rrn.onnx");
  write_file(tmp / "models" / "rrn.onnx", bytes.substr(0, bytes.size() / 2));
  expect_clean_failure(remove({"in.png", "out.png", "--models", "models"}), "rrn.onnx");
}

// One image is decoded beside the models' loading (remove_main.cpp): a broken model folder is
// still the error reported first, as when the image was read after the models, and a cut image
// with good models is still reported as cut.
TEST_F(RemoveCli, BrokenModelsAreReportedBeforeABrokenImage) {
  fs::create_directories(tmp / "models");
  for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) fs::copy_file(smoke_models() / f, tmp / "models" / f);
  const std::string model = read_file(tmp / "models" / "rrn.onnx");
  write_file(tmp / "models" / "rrn.onnx", model.substr(0, model.size() / 2));
  const std::string image = read_file(tmp / "in.png");
  write_file(tmp / "cut.png", image.substr(0, image.size() / 2));
  RunResult r = remove({"cut.png", "out.png", "--models", "models"});
  expect_clean_failure(r, "rrn.onnx");
  EXPECT_EQ(r.err.find("truncated"), std::string::npos) << r.describe();
  fs::copy_file(smoke_models() / "rrn.onnx", tmp / "models" / "rrn.onnx", fs::copy_options::overwrite_existing);
  expect_clean_failure(remove({"cut.png", "out.png", "--models", "models"}), "truncated");
}

TEST_F(RemoveCli, MissingLargeDropModels) {
  expect_clean_failure(remove({"in.png", "out.png", "--large-drop-models", "nowhere"}), "nowhere");
}

// --time names the models that take the large drops (the models' LARGE_DROPS, or the option).
TEST_F(RemoveCli, TimeNamesTheLargeDropModels) {
  fs::create_directories(tmp / "models" / "main");
  for (const char* f : {"rdn.onnx", "rrn.onnx", "rfn.onnx"}) {
    fs::copy_file(smoke_models() / f, tmp / "models" / "main" / f);
    fs::create_directories(tmp / "models" / "big");
    fs::copy_file(smoke_models() / f, tmp / "models" / "big" / f);
  }
  write_file(tmp / "models" / "main" / "LARGE_DROPS", "big\n");
  RunResult r = remove({"in.png", "out.png", "--time", "--models", "models/main"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("large drops by '" + fs::weakly_canonical(tmp / "models" / "big").string() + "'"), std::string::npos)
      << r.describe();
  r = remove({"in.png", "out2.png", "--time", "--models", "models/main", "--large-drop-models", "models/main"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("large drops by the same models"), std::string::npos) << r.describe();
  fs::remove_all(tmp / "models" / "big");
  fs::remove(tmp / "out.png");
  fs::remove(tmp / "out2.png");
  // LARGE_DROPS names a folder that is gone: refused, naming the file and the way out ...
  r = remove({"in.png", "out.png", "--models", "models/main"});
  expect_clean_failure(r, "LARGE_DROPS");
  EXPECT_NE(r.err.find("--no-large-drops"), std::string::npos) << r.describe();
  // ... which works: without the coarse pass the large-drop models are not needed.
  r = remove({"in.png", "out.png", "--models", "models/main", "--no-large-drops"});
  EXPECT_EQ(r.code, 0) << r.describe();
}

TEST_F(RemoveCli, MissingModelFolder) { expect_clean_failure(remove({"in.png", "out.png", "--models", "nowhere"}), "nowhere"); }

TEST_F(RemoveCli, UnwritableOutputPath) {
  write_file(tmp / "afile", "x");
  const RunResult r = remove({"in.png", "afile/out.png"});
  expect_clean_failure(r, "afile/out.png");
  EXPECT_EQ(read_file(tmp / "afile"), "x");
}

TEST_F(RemoveCli, OutputFolderMissing) {
  expect_clean_failure(remove({"in.png", "no/such/dir/out.png"}), "out.png");
  // The mask's folder is checked before anything is written.
  expect_clean_failure(remove({"in.png", "out.png", "--mask", "nodir/mask.png"}), "nodir");
}

TEST_F(RemoveCli, UnknownOutputFormat) { expect_clean_failure(remove({"in.png", "out.unknownext"}), "out.unknownext"); }

// Whether to skip is decided by what ONNX Runtime itself reports, not by the program's exit
// code: a program that quietly ran on the CPU after --device cuda must fail this test.
TEST_F(RemoveCli, CudaWithoutTheProvider) {
  const std::vector<std::string> providers = Ort::GetAvailableProviders();
  if (std::find(providers.begin(), providers.end(), "CUDAExecutionProvider") != providers.end())
    GTEST_SKIP() << "this ONNX Runtime has the CUDA provider; the error path cannot be checked here";
  const RunResult r = remove({"in.png", "out.png", "--device", "cuda"});
  ASSERT_NE(r.code, 0) << "--device cuda succeeded although ONNX Runtime has no CUDA provider (available: "
                       << ::testing::PrintToString(providers) << ")\n"
                       << r.describe();
  expect_clean_failure(r, "CUDA");
}

// The GPU build (cmake -DRAINDROP_ONNXRUNTIME_GPU=ON): --device cuda either runs on the GPU
// and gives the CPU's result (up to float rounding, which may flip a few mask pixels at the
// threshold), or, where CUDA, cuDNN or a GPU is missing, fails with our one line naming what is
// missing and writes nothing. Never a crash, a hang or an unexplained failure.
TEST_F(RemoveCli, CudaWithTheProvider) {
  const std::vector<std::string> providers = Ort::GetAvailableProviders();
  if (std::find(providers.begin(), providers.end(), "CUDAExecutionProvider") == providers.end())
    GTEST_SKIP() << "this ONNX Runtime is the CPU build (the default); configure with "
                    "-DRAINDROP_ONNXRUNTIME_GPU=ON to check the CUDA path";
  const RunResult r = remove({"in.png", "out.png", "--mask", "mask.png", "--device", "cuda"});
  if (r.code != 0) {
    expect_clean_failure(r, "CUDA");
    const bool names_a_library = r.err.find("cannot open shared object file") != std::string::npos;
    const bool gpu_present = fs::exists("/dev/nvidiactl") || fs::exists("/dev/nvidia0");
    EXPECT_TRUE(names_a_library || !gpu_present)
        << "a GPU is present and --device cuda failed without naming a missing library\n" << r.describe();
    return;
  }
  ASSERT_TRUE(r.err.empty()) << r.describe();
  const RunResult cpu = remove({"in.png", "cpu.png", "--mask", "cpu-mask.png", "--device", "cpu"});
  ASSERT_EQ(cpu.code, 0) << cpu.describe();
  const auto out_gpu = read_image(tmp / "out.png"), out_cpu = read_image(tmp / "cpu.png");
  const auto mask_gpu = read_image(tmp / "mask.png"), mask_cpu = read_image(tmp / "cpu-mask.png");
  ASSERT_TRUE(out_gpu && out_cpu && mask_gpu && mask_cpu);
  cv::Mat diff;
  cv::absdiff(out_gpu->pixels, out_cpu->pixels, diff);
  const double far = cv::countNonZero(diff.reshape(1) > 2) / static_cast<double>(diff.total() * diff.channels());
  const double flipped = cv::countNonZero(mask_gpu->pixels != mask_cpu->pixels) / static_cast<double>(mask_cpu->pixels.total());
  EXPECT_LE(flipped, 0.01) << "GPU and CPU masks differ in more than 1% of the pixels";
  EXPECT_LE(far, 0.01) << "GPU and CPU outputs differ by more than 2 levels in more than 1% of the values";
}

// Float images hold linear light: refused in one line (they used to come out clamped and
// linear), and a folder's EXR files are not inputs.
TEST_F(RemoveCli, FloatImagesAreRefusedAndSkippedInFolders) {
  {
    auto out = OIIO::ImageOutput::create((tmp / "lin.exr").string());
    ASSERT_TRUE(out);
    const std::vector<float> px(40 * 30 * 3, 0.25f);
    OIIO::ImageSpec spec(40, 30, 3, OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open((tmp / "lin.exr").string(), spec) && out->write_image(OIIO::TypeDesc::FLOAT, px.data()) &&
                out->close());
  }
  const RunResult r = remove({"lin.exr", "out.png"});
  expect_clean_failure(r, "float");
  fs::create_directories(tmp / "folder");
  fs::rename(tmp / "lin.exr", tmp / "folder" / "lin.exr");
  fs::copy_file(tmp / "in.png", tmp / "folder" / "in.png");
  const RunResult f = remove({"folder", "done", "-q"});
  ASSERT_EQ(f.code, 0) << f.describe();
  EXPECT_TRUE(fs::exists(tmp / "done" / "in.png"));
  EXPECT_FALSE(fs::exists(tmp / "done" / "lin.exr"));
}

// PNG and JPEG go through libpng and libjpeg: OpenImageIO, whose libraries cost 200 ms of start-up,
// is loaded (as the raindrop_oiio plugin) only for another format. The dynamic loader lists
// every library it loads (LD_DEBUG=files), including those opened with dlopen.
TEST_F(RemoveCli, OpenImageIOLoadsOnlyForOtherFormats) {
  write_image(tmp / "in.jpg", make_image(61, 43, 2));
  write_image(tmp / "in.tif", make_image(61, 43, 3));
  const std::string models = smoke_models().string();
  // What the loader loaded: OpenImageIO (by any route), and the plugin.
  auto loaded = [&](const std::string& in, const std::string& out) {
    const RunResult r = remove({in, out, "--models", models}, {"LD_DEBUG=files"});
    EXPECT_EQ(r.code, 0) << r.describe();
    EXPECT_TRUE(fs::exists(tmp / out)) << r.describe();
    return std::make_pair(r.err.find("libOpenImageIO") != std::string::npos,
                          r.err.find("raindrop_oiio.so") != std::string::npos);
  };
  EXPECT_EQ(loaded("in.png", "out.png"), std::make_pair(false, false));
  EXPECT_EQ(loaded("in.jpg", "out.jpg"), std::make_pair(false, false));
  EXPECT_EQ(loaded("in.tif", "out1.png"), std::make_pair(true, true));
  EXPECT_EQ(loaded("in.png", "out2.tif"), std::make_pair(true, true));
}

// Without the plugin, PNG and JPEG still work, and another format fails in one line that says why.
TEST_F(RemoveCli, MissingOpenImageIOPluginIsOneLine) {
  write_image(tmp / "in.tif", make_image(61, 43, 3));
  const std::vector<std::string> no_plugin = {"RAINDROP_OIIO_PLUGIN=" + (tmp / "none.so").string()};
  const std::string models = smoke_models().string();
  const RunResult ok = remove({"in.png", "ok.jpg", "--models", models}, no_plugin);
  EXPECT_EQ(ok.code, 0) << ok.describe();
  const RunResult r = remove({"in.tif", "out.png", "--models", models}, no_plugin);
  expect_clean_failure(r, "needs OpenImageIO");
  EXPECT_NE(r.err.find("none.so"), std::string::npos) << r.describe();
  expect_clean_failure(remove({"in.png", "out.tif", "--models", models}, no_plugin), "out.tif");
}

// An installed tree (cmake --install) finds its plugin in lib/raindrop: a TIFF in, a TIFF out.
TEST_F(RemoveCli, InstalledProgramReadsAndWritesOtherFormats) {
  const fs::path build = remove_bin().parent_path();
  const RunResult install = run_command("cmake", {"--install", build.string(), "--prefix", (tmp / "inst").string()}, tmp.path());
  ASSERT_EQ(install.code, 0) << install.describe();
  ASSERT_TRUE(fs::exists(tmp / "inst" / "lib" / "raindrop" / "raindrop_oiio.so"));
  write_image(tmp / "in.tif", make_image(61, 43, 3));
  const RunResult r = run_command(tmp / "inst" / "bin" / "raindrop-remove",
                                  {"in.tif", "out.tif", "--models", smoke_models().string()}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto out = read_image(tmp / "out.tif");
  ASSERT_TRUE(out);
  EXPECT_EQ(out->pixels.size(), cv::Size(61, 43));
  // The installed default routes as the source tree's does: its ROUTER and the detector it
  // names are installed with it.
  const fs::path source_default = source_dir() / "models" / "compact-multiscale";
  if (fs::exists(source_default / "ROUTER")) {
    EXPECT_TRUE(fs::exists(tmp / "inst" / "share" / "raindrop" / "models" / "compact-multiscale" / "ROUTER"));
    const RunResult routed = run_command(tmp / "inst" / "bin" / "raindrop-remove",
                                         {"in.tif", "routed.png", "--model-config", "compact-multiscale", "--time"}, tmp.path());
    ASSERT_EQ(routed.code, 0) << routed.describe();
    EXPECT_NE(routed.err.find("share/raindrop/models/compact-windshield"), std::string::npos) << routed.describe();
    EXPECT_NE(routed.err.find("router z "), std::string::npos) << routed.describe();
  }
}

// --large-drop-sharpness reaches the coarse pass: on a finely textured (sharp) image that is one
// drop all over, the default limit leaves the coarse pass nothing to replace, and `inf` lets it
// take the whole image; --time says so, and names the limit in effect.
TEST_F(RemoveCli, LargeDropSharpnessReachesTheCoarsePass) {
  cv::Mat sharp = make_image(600, 300, 14), grain(sharp.size(), CV_8UC3);
  cv::randu(grain, 0, 48);
  sharp += grain;
  write_image(tmp / "sharp.png", sharp);
  RunResult r = remove({"sharp.png", "a.png", "--threshold", "0", "--time"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("large-drop sharpness 8;"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find(", 0 large drops (1 more left alone: too sharp) at scale"), std::string::npos) << r.describe();
  r = remove({"sharp.png", "b.png", "--threshold", "0", "--time", "--large-drop-sharpness", "inf"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("large-drop sharpness inf;"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find(", 1 large drop at scale"), std::string::npos) << r.describe();
  const auto a = read_image(tmp / "a.png"), b = read_image(tmp / "b.png");
  ASSERT_TRUE(a && b);
  EXPECT_GT(max_abs_diff(a->pixels, b->pixels), 0);
  r = remove({"sharp.png", "c.png", "--threshold", "0", "--time", "--no-large-drops"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.err.find("large-drop sharpness"), std::string::npos) << "no coarse pass, no limit to name\n" << r.describe();
  // --large-drop-detail reaches it too: 0 gives the fill alone, which differs from the default's
  // fill with the input's detail; outside the large drop's reach both are the same pixels.
  r = remove({"sharp.png", "d.png", "--threshold", "0", "--large-drop-sharpness", "inf", "--large-drop-detail", "0"});
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto d = read_image(tmp / "d.png");
  ASSERT_TRUE(d);
  EXPECT_GT(max_abs_diff(b->pixels, d->pixels), 10) << "the default gives back no detail";
}

// --surround-fill-area reaches the pipeline and --time counts the parts filled: small dark dots
// on a smooth gradient, found by a threshold of 0.25 on the fixture models' detector (0.7% of the image), are filled
// by default (a count above zero) and not with 0, and the two outputs differ.
TEST_F(RemoveCli, SurroundFillIsCountedAndCanBeTurnedOff) {
  cv::Mat img(96, 128, CV_8UC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<unsigned char>(100 + x / 2), static_cast<unsigned char>(140 + y / 4), 170);
  for (int k = 0; k < 6; ++k) cv::circle(img, {15 + 20 * k, 20 + 10 * k}, 2, cv::Scalar(20, 20, 20), cv::FILLED);
  write_image(tmp / "dots.png", img);
  RunResult r = remove({"dots.png", "a.png", "--time", "--surround-fill-mad", "255", "--no-large-drops", "--threshold",
                        "0.25", "--mask", "m.png"});
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto m = read_image(tmp / "m.png");
  ASSERT_TRUE(m);
  const int masked = cv::countNonZero(m->pixels);
  ASSERT_GT(masked, 0) << "the detector must find something here for the test to mean anything";
  ASSERT_LT(masked, img.rows * img.cols / 4);
  EXPECT_EQ(r.err.find(" 0 small drops filled"), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("filled from the surround"), std::string::npos) << r.describe();
  r = remove({"dots.png", "b.png", "--time", "--surround-fill-mad", "255", "--no-large-drops", "--threshold", "0.25",
              "--surround-fill-area", "0"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.err.find("filled from the surround"), std::string::npos) << "off: nothing to count\n" << r.describe();
  const auto a = read_image(tmp / "a.png"), b = read_image(tmp / "b.png");
  ASSERT_TRUE(a && b);
  EXPECT_GT(max_abs_diff(a->pixels, b->pixels), 0);
}

// --mirror-average changes the fills (the 3RN and RFN also run on the mirror image), not the mask.
// (Without the coarse pass, which would take the whole image over as one large drop: it mirrors
// either way.)
TEST_F(RemoveCli, MirrorAverageChangesTheFillsNotTheMask) {
  write_image(tmp / "big.png", make_image(200, 120, 5));
  const std::string models = (source_dir() / "models" / "compact").string();  // the smoke models' fills are too flat
  const std::vector<std::string> common = {"big.png", "--threshold", "0", "--no-large-drops", "--models", models};
  auto with = [&](std::vector<std::string> args) {
    args.insert(args.begin(), common.begin(), common.end());
    return remove(args);
  };
  ASSERT_EQ(with({"a.png", "--mask", "ma.png"}).code, 0);
  const RunResult r = with({"b.png", "--mask", "mb.png", "--mirror-average"});
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto a = read_image(tmp / "a.png"), b = read_image(tmp / "b.png");
  const auto ma = read_image(tmp / "ma.png"), mb = read_image(tmp / "mb.png");
  ASSERT_TRUE(a && b && ma && mb);
  EXPECT_EQ(max_abs_diff(ma->pixels, mb->pixels), 0);
  EXPECT_GT(max_abs_diff(a->pixels, b->pixels), 0) << "--mirror-average changed nothing";
}

TEST_F(RemoveCli, ModelsFromTheEnvironment) {
  // A model folder...
  RunResult r = remove({"in.png", "out.png"}, {"RAINDROP_MODELS=" + smoke_models().string()});
  ASSERT_EQ(r.code, 0) << r.describe();
  fs::remove(tmp / "out.png");
  // ... or a folder of configurations with DEFAULT naming one, or --model-config.
  fs::create_directories(tmp / "root");
  fs::create_directory_symlink(smoke_models(), tmp / "root" / "smoke");
  write_file(tmp / "root" / "DEFAULT", "smoke\n");
  r = remove({"in.png", "out.png", "--time"}, {"RAINDROP_MODELS=" + (tmp / "root").string()});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("root/smoke"), std::string::npos) << r.describe();
  r = remove({"in.png", "out2.png", "--model-config", "smoke"}, {"RAINDROP_MODELS=" + (tmp / "root").string()});
  ASSERT_EQ(r.code, 0) << r.describe();
  fs::remove(tmp / "out.png");
  fs::remove(tmp / "out2.png");
  // DEFAULT's int8 copy ("vnni NAME") where this CPU runs int8 fast, said on the models line;
  // --model-config names the first line's folder itself.
  fs::create_directory_symlink(smoke_models(), tmp / "root" / "smoke-int8");
  write_file(tmp / "root" / "DEFAULT", "smoke\nvnni smoke-int8\n");
  const bool int8 = raindrop::removal::int8_runs_fast();
  r = remove({"in.png", "out.png", "--time"}, {"RAINDROP_MODELS=" + (tmp / "root").string()});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_EQ(r.err.find("root/smoke-int8'") != std::string::npos, int8) << r.describe();
  EXPECT_EQ(r.err.find("(DEFAULT's int8 copy of smoke: this CPU has VNNI)") != std::string::npos, int8) << r.describe();
  r = remove({"in.png", "out2.png", "--time", "--model-config", "smoke"}, {"RAINDROP_MODELS=" + (tmp / "root").string()});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("root/smoke'"), std::string::npos) << r.describe();
  EXPECT_EQ(r.err.find("int8 copy"), std::string::npos) << r.describe();
  fs::remove(tmp / "out.png");
  fs::remove(tmp / "out2.png");
  write_file(tmp / "root" / "DEFAULT", "smoke\nvnni\n");
  r = remove({"in.png", "out.png"}, {"RAINDROP_MODELS=" + (tmp / "root").string()});
  expect_clean_failure(r, "vnni NAME");
  // Nothing there: a clear error naming the variable.
  fs::create_directories(tmp / "empty");
  r = remove({"in.png", "out.png"}, {"RAINDROP_MODELS=" + (tmp / "empty").string()});
  expect_clean_failure(r, "RAINDROP_MODELS");
}

TEST_F(RemoveCli, FormatsAreKept) {
  cv::Mat rgb8 = make_image(23, 19, 5), grey8, alpha8(19, 23, CV_8U);
  cv::cvtColor(rgb8, grey8, cv::COLOR_RGB2GRAY);
  cv::randu(alpha8, 0, 256);
  cv::Mat rgba8, ga8, rgb16, rgba16, grey16, ga16;
  cv::merge(std::vector<cv::Mat>{rgb8, alpha8}, rgba8);
  cv::merge(std::vector<cv::Mat>{grey8, alpha8}, ga8);
  rgb8.convertTo(rgb16, CV_16U, 257.0);
  rgba8.convertTo(rgba16, CV_16U, 257.0);
  grey8.convertTo(grey16, CV_16U, 257.0);
  ga8.convertTo(ga16, CV_16U, 257.0);
  const std::vector<std::pair<std::string, cv::Mat>> images = {
      {"rgb8.png", rgb8},   {"grey8.png", grey8},   {"ga8.png", ga8},  {"rgba8.png", rgba8},
      {"rgb16.png", rgb16}, {"grey16.png", grey16}, {"ga16.png", ga16}, {"rgba16.png", rgba16},
      {"rgb8.tif", rgb8},   {"rgba16.tif", rgba16}};
  for (const auto& [name, img] : images) {
    SCOPED_TRACE(name);
    write_image(tmp / "fmt" / name, img);
    const RunResult r = remove({"fmt/" + name, "fmt/out_" + name});
    ASSERT_EQ(r.code, 0) << r.describe();
    const auto in = read_image(tmp / "fmt" / name);
    const auto out = read_image(tmp / "fmt" / ("out_" + name));
    ASSERT_TRUE(in && out);
    EXPECT_EQ(out->width, in->width);
    EXPECT_EQ(out->height, in->height);
    EXPECT_EQ(out->channels, in->channels);
    EXPECT_EQ(out->format, in->format);
    if (in->channels == 2 || in->channels == 4) {
      cv::Mat a_in, a_out;
      cv::extractChannel(in->pixels, a_in, in->channels - 1);
      cv::extractChannel(out->pixels, a_out, in->channels - 1);
      EXPECT_EQ(cv::countNonZero(a_in != a_out), 0) << "alpha changed";
    }
  }
}

TEST_F(RemoveCli, FolderMode) {
  write_image(tmp / "batch" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "batch" / "sub" / "b.png", make_image(17, 33, 2));
  write_image(tmp / "batch" / "sub" / "deeper" / "c.tif", make_image(20, 20, 3));
  write_file(tmp / "batch" / "notes.txt", "not an image, not touched");
  const RunResult r = remove({"batch", "results", "--mask-dir", "masks", "--contact-sheet", "sheet.png"});
  ASSERT_EQ(r.code, 0) << r.describe();
  for (const char* rel : {"a.png", "sub/b.png", "sub/deeper/c.tif"}) {
    const auto in = read_image(tmp / "batch" / rel);
    const auto out = read_image(tmp / "results" / rel);
    ASSERT_TRUE(in && out) << rel;
    EXPECT_EQ(out->width, in->width) << rel;
    EXPECT_TRUE(read_image((tmp / "masks" / rel).replace_extension(".png"))) << rel;
  }
  EXPECT_FALSE(fs::exists(tmp / "results" / "notes.txt"));
  EXPECT_TRUE(read_image(tmp / "sheet.png"));
  EXPECT_NE(r.err.find("remove ["), std::string::npos) << "progress bar expected\n" << r.describe();
  EXPECT_NE(r.err.find("3 of 3 images done"), std::string::npos) << r.describe();
  // Output folder inside the input folder: its files are not taken as inputs on a re-run.
  const RunResult again = remove({"batch", "batch/out", "-q", "--mask", "masks2"});
  ASSERT_EQ(again.code, 0) << again.describe();
  EXPECT_FALSE(fs::exists(tmp / "batch" / "out" / "out"));
  EXPECT_EQ(again.err, "") << "-q: nothing on stderr";
  EXPECT_TRUE(read_image(tmp / "masks2" / "sub" / "deeper" / "c.png")) << "--mask is a folder in folder mode";
  // --mask-dir with one image: <dir>/<name>.png; --mask and --mask-dir together are a usage error.
  const RunResult one = remove({"batch/sub/b.png", "b_out.png", "--mask-dir", "m"});
  ASSERT_EQ(one.code, 0) << one.describe();
  EXPECT_TRUE(read_image(tmp / "m" / "b.png"));
  EXPECT_EQ(remove({"batch/a.png", "a_out.png", "--mask", "x.png", "--mask-dir", "m"}).code, 2);
}

// Folder mode reads every input's header before anything is written: an image refused from
// its header (here: not an image, a float EXR-like TIFF, five channels), third in the folder,
// used to stop the run after the first two outputs were written. It is refused before the
// models load (a missing model folder is not what the error names) and no output folder is made.
TEST_F(RemoveCli, FolderModeRefusesBadHeadersBeforeTheFirstWrite) {
  cv::Mat floating(30, 40, CV_32FC3, cv::Scalar(0.5, 0.25, 0.125));
  cv::Mat grey = make_image(40, 30, 3), five;
  cv::cvtColor(make_image(40, 30, 3), grey, cv::COLOR_RGB2GRAY);
  cv::merge(std::vector<cv::Mat>{grey, grey, grey, grey, grey}, five);
  for (const auto& [name, pixels] : std::vector<std::pair<std::string, cv::Mat>>{
           {"c.png", cv::Mat()}, {"c.tif", floating}, {"c_five.tif", five}}) {
    SCOPED_TRACE(name);
    const fs::path in = tmp / ("h-" + fs::path(name).filename().string());
    write_image(in / "a.png", make_image(40, 30, 1));
    write_image(in / "b.png", make_image(40, 30, 2));
    if (pixels.empty()) {
      write_file(in / name, "not an image");
    } else {
      write_image(in / name, pixels);
    }
    const std::string out = "out-" + in.filename().string();
    RunResult r = remove({in.filename().string(), out, "-q", "-j", "1", "--models", "no-such-models"});
    EXPECT_EQ(r.code, 1) << r.describe();
    ASSERT_EQ(r.err_lines().size(), 1u) << r.describe();
    EXPECT_NE(r.err.find(name), std::string::npos) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / out)) << "nothing may be written before a refusal found in a header";
    // --keep-going: the others are done, the refused one is counted as failed.
    r = remove({in.filename().string(), out, "-q", "--keep-going"});
    EXPECT_EQ(r.code, 3) << r.describe();
    EXPECT_TRUE(fs::exists(tmp / out / "a.png"));
    EXPECT_TRUE(fs::exists(tmp / out / "b.png"));
    EXPECT_NE(r.err.find("2 of 3 images done, 1 failed"), std::string::npos) << r.describe();
  }
}

// An output name the file system refuses (over 255 bytes) is refused before the models load;
// one at the limit is written (its temporary used to be too long, after the inference).
TEST_F(RemoveCli, LongOutputNames) {
  const std::string longest = std::string(251, 'a') + ".png", too_long = std::string(252, 'a') + ".png";
  RunResult r = remove({"in.png", too_long, "-q", "--models", "no-such-models"});
  EXPECT_EQ(r.code, 1) << r.describe();
  ASSERT_EQ(r.err_lines().size(), 1u) << r.describe();
  EXPECT_NE(r.err.find("256 bytes, longer than the 255"), std::string::npos) << r.describe();
  r = remove({"in.png", "out.png", "-q", "--mask", too_long, "--models", "no-such-models"});
  EXPECT_NE(r.err.find("256 bytes"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out.png"));
  r = remove({"in.png", longest, "-q"});
  EXPECT_EQ(r.code, 0) << r.describe();
  EXPECT_TRUE(read_image(tmp / longest)) << r.describe();
}

// A folder of symbolic links to images elsewhere: each output lands under the output folder
// at its link's name. Resolving the links put the output beside the link's target
// ("results/../elsewhere/in.png", the input itself, refused as such).
TEST_F(RemoveCli, FolderOfSymlinksWritesUnderTheOutputFolder) {
  fs::create_directories(tmp / "picked");
  fs::create_symlink(fs::absolute(tmp / "in.png"), tmp / "picked" / "first.png");
  const auto before = read_image(tmp / "in.png");
  const RunResult r = remove({"picked", "results", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_TRUE(read_image(tmp / "results" / "first.png")) << r.describe();
  const auto after = read_image(tmp / "in.png");
  ASSERT_TRUE(before && after);
  EXPECT_EQ(max_abs_diff(before->pixels, after->pixels), 0) << "the link's target is an input, never written";
}

TEST_F(RemoveCli, FolderModeFailures) {
  write_image(tmp / "batch" / "a.png", make_image(40, 30, 1));
  write_file(tmp / "batch" / "b.png", "broken");
  write_image(tmp / "batch" / "c.png", make_image(20, 30, 2));
  RunResult r = remove({"batch", "stop", "-q"});
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("b.png"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "stop" / "b.png"));
  EXPECT_FALSE(fs::exists(tmp / "stop" / "c.png")) << "without --keep-going the run stops at the first failure";
  r = remove({"batch", "go", "-q", "--keep-going"});
  EXPECT_EQ(r.code, 3) << r.describe();
  EXPECT_TRUE(fs::exists(tmp / "go" / "a.png"));
  EXPECT_TRUE(fs::exists(tmp / "go" / "c.png"));
  EXPECT_FALSE(fs::exists(tmp / "go" / "b.png"));
  EXPECT_NE(r.err.find("raindrop-remove: failed: "), std::string::npos) << r.describe();
  EXPECT_NE(r.err.find("2 of 3 images done, 1 failed"), std::string::npos) << r.describe();
  // A folder input needs a folder output.
  write_file(tmp / "plain", "x");
  r = remove({"batch", "plain"});
  EXPECT_EQ(r.code, 1) << r.describe();
  // The input folder as the output folder would overwrite the inputs: a usage error.
  r = remove({"batch", "batch/"});
  EXPECT_EQ(r.code, 2) << r.describe();
  EXPECT_NE(r.err.find("input folder"), std::string::npos) << r.describe();
  // An empty folder is an error, not a silent success.
  fs::create_directories(tmp / "nothing");
  r = remove({"nothing", "out"});
  EXPECT_EQ(r.code, 1) << r.describe();
}


// An output or mask folder inside the input folder is left out of the inputs, so an image
// already there may be the user's own: photos/a.png's output would be photos/2023/a.png.
// Refused before anything is written; a fresh folder there is still fine.
TEST_F(RemoveCli, AFolderInsideTheInputNeverHasAFileReplaced) {
  write_image(tmp / "photos" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "photos" / "2023" / "a.png", make_image(50, 20, 2));
  write_image(tmp / "photos" / "2024" / "a.png", make_image(50, 20, 3));
  const std::string mine = read_file(tmp / "photos" / "2023" / "a.png");
  for (const std::vector<std::string>& args : {std::vector<std::string>{"photos", "photos/2023"},
                                               {"photos", "out", "--mask-dir", "photos/2024"}}) {
    const RunResult r = remove(args);
    SCOPED_TRACE(r.command);
    EXPECT_EQ(r.code, 2) << r.describe();
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_NE(lines[0].find("already exists"), std::string::npos) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out"));
  }
  EXPECT_EQ(read_file(tmp / "photos" / "2023" / "a.png"), mine);
  // A folder this program made there may be run into again: its files are its own outputs.
  for (int run = 0; run < 2; ++run) {
    const RunResult fresh = remove({"photos", "photos/derained", "--mask-dir", "photos/masks", "-q"});
    EXPECT_EQ(fresh.code, 0) << "run " << run << "\n" << fresh.describe();
    EXPECT_TRUE(fs::exists(tmp / "photos" / "derained" / "a.png"));
    EXPECT_TRUE(fs::exists(tmp / "photos" / "derained" / "2023" / "a.png"));
    EXPECT_TRUE(fs::exists(tmp / "photos" / "masks" / "2023" / "a.png"));
  }
}

// An output folder that holds the input folder: every image under the input is an input
// (skipping the output folder used to skip all the input's subfolders, silently).
TEST_F(RemoveCli, AnOutputFolderHoldingTheInputSkipsNoSubfolder) {
  write_image(tmp / "x" / "imgs" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "x" / "imgs" / "sub" / "c.png", make_image(20, 30, 2));
  const RunResult r = remove({"x/imgs", "x"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("2 of 2 images done"), std::string::npos) << r.describe();
  EXPECT_TRUE(fs::exists(tmp / "x" / "a.png"));
  EXPECT_TRUE(fs::exists(tmp / "x" / "sub" / "c.png"));
}

// A folder that holds the input or lies inside it replaces only the files an earlier run wrote
// there, as its list names them. A folder-wide mark used to be written into such a folder even
// when it already held the user's photographs, and every later run then replaced them.
TEST_F(RemoveCli, ANestedFolderReplacesOnlyWhatItsListNames) {
  write_image(tmp / "photos" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "photos" / "2023" / "b.png", make_image(50, 20, 2));  // the user's own
  const std::string mine = read_file(tmp / "photos" / "2023" / "b.png");
  ASSERT_EQ(remove({"photos", "photos/2023", "-q"}).code, 0);  // writes photos/2023/a.png only
  write_image(tmp / "photos" / "b.png", make_image(40, 30, 3));  // its output would be 2023/b.png
  const RunResult r = remove({"photos", "photos/2023", "-q"});
  EXPECT_EQ(r.code, 2) << r.describe();
  EXPECT_NE(r.err.find("'photos/2023/b.png' already exists"), std::string::npos) << r.describe();
  EXPECT_EQ(read_file(tmp / "photos" / "2023" / "b.png"), mine);
  fs::remove(tmp / "photos" / "b.png");
  const std::string first = read_file(tmp / "photos" / "2023" / "a.png");
  write_image(tmp / "photos" / "a.png", make_image(40, 30, 4));
  const RunResult again = remove({"photos", "photos/2023", "-q"});  // its own output: replaced
  ASSERT_EQ(again.code, 0) << again.describe();
  EXPECT_NE(read_file(tmp / "photos" / "2023" / "a.png"), first);
  EXPECT_EQ(read_file(tmp / "photos" / "2023" / "b.png"), mine);
}

// The list records each file as written (size, modification time): a photograph the user put
// where an earlier output of the same name had been is not taken for that output, and a link
// there (even one that leads nowhere) is not replaced either.
TEST_F(RemoveCli, AListedNameIsNotEnoughToReplaceAFile) {
  write_image(tmp / "photos" / "wet" / "IMG_1.png", make_image(40, 30, 1));
  write_image(tmp / "photos" / "wet" / "IMG_2.png", make_image(40, 30, 2));
  ASSERT_EQ(remove({"photos/wet", "photos", "-q"}).code, 0);  // writes photos/IMG_1.png, IMG_2.png
  fs::remove(tmp / "photos" / "IMG_1.png");
  write_image(tmp / "photos" / "IMG_1.png", make_image(50, 20, 3));  // the user's own, same name
  const std::string mine = read_file(tmp / "photos" / "IMG_1.png");
  const RunResult r = remove({"photos/wet", "photos", "-q"});
  EXPECT_EQ(r.code, 2) << r.describe();
  EXPECT_NE(r.err.find("'photos/IMG_1.png' already exists"), std::string::npos) << r.describe();
  EXPECT_EQ(read_file(tmp / "photos" / "IMG_1.png"), mine);
  fs::remove(tmp / "photos" / "IMG_1.png");
  fs::create_symlink(tmp / "nowhere.png", tmp / "photos" / "IMG_1.png");
  EXPECT_EQ(remove({"photos/wet", "photos", "-q"}).code, 2);
  EXPECT_TRUE(fs::is_symlink(tmp / "photos" / "IMG_1.png"));
  fs::remove(tmp / "photos" / "IMG_1.png");
  const RunResult again = remove({"photos/wet", "photos", "-q"});  // IMG_2.png is its own, unchanged
  EXPECT_EQ(again.code, 0) << again.describe();
}

// The list is appended after each file written: one the run may not write (read-only, for
// root too) stops it before its first output, not after it with exit 1 and an output on disk.
TEST_F(RemoveCli, AReadOnlyListStopsTheRunBeforeAnyOutput) {
  write_image(tmp / "photos" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "photos" / "b.png", make_image(40, 30, 2));
  ASSERT_EQ(remove({"photos", "photos/clean", "-q"}).code, 0);
  const fs::path list = tmp / "photos" / "clean" / ".raindrop-remove-outputs";
  ASSERT_TRUE(fs::exists(list));
  fs::remove(tmp / "photos" / "clean" / "a.png");
  fs::remove(tmp / "photos" / "clean" / "b.png");
  fs::permissions(list, fs::perms::owner_read);
  const RunResult r = remove({"photos", "photos/clean", "-q"});
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_EQ(split_lines(r.err).size(), 1u) << r.describe();
  EXPECT_NE(r.err.find(".raindrop-remove-outputs"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "photos" / "clean" / "a.png"));
  EXPECT_FALSE(fs::exists(tmp / "photos" / "clean" / "b.png"));
  EXPECT_TRUE(hidden_temporaries(tmp / "photos" / "clean").empty());
}

// A full disk can leave the list without its header (made, then its first write failed) or
// with a record cut short. Neither may cost the records written after it: with the first record
// taken for the header, or the next record run into the cut one, each later run refused the
// files this program had written itself.
TEST_F(RemoveCli, AListCutShortByAFullDiskKeepsTheRecordsAfterIt) {
  write_image(tmp / "photos" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "photos" / "b.png", make_image(40, 30, 2));
  ASSERT_EQ(remove({"photos", "photos/clean", "-q"}).code, 0);
  const fs::path list = tmp / "photos" / "clean" / ".raindrop-remove-outputs";
  write_file(list, "");  // the header's write failed
  fs::remove(tmp / "photos" / "clean" / "a.png");
  fs::remove(tmp / "photos" / "clean" / "b.png");
  RunResult r = remove({"photos", "photos/clean", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  r = remove({"photos", "photos/clean", "-q"});
  ASSERT_EQ(r.code, 0) << "its own outputs, recorded after a list with no header\n" << r.describe();
  // Not a plain file at the list's name: refused before any output (a folder there failed the
  // first append, after the first output).
  const fs::path moved = tmp / "list-aside";
  fs::rename(list, moved);
  fs::create_directory(list);
  fs::remove(tmp / "photos" / "clean" / "a.png");
  r = remove({"photos", "photos/clean", "-q"});
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("is not a plain file"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "photos" / "clean" / "a.png"));
  fs::remove(list);
  fs::rename(moved, list);
  r = remove({"photos", "photos/clean", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  std::ofstream(list, std::ios::app) << "31 17";  // a record cut short
  fs::remove(tmp / "photos" / "clean" / "b.png");
  r = remove({"photos", "photos/clean", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  r = remove({"photos", "photos/clean", "-q"});
  EXPECT_EQ(r.code, 0) << "b.png, recorded after a record cut short\n" << r.describe();
}

// An output folder that holds the input folder (photos/ for photos/wet/) may hold the user's
// photographs under the names its outputs take: refused, as for a folder inside the input.
// The same with a single image whose mask folder is the image's own folder (a.jpg's mask is
// a.png there), and across shards: each shard checks every shard's files.
TEST_F(RemoveCli, AFolderHoldingTheInputNeverHasAFileReplaced) {
  write_image(tmp / "P" / "wet" / "im.png", make_image(40, 30, 1));
  write_image(tmp / "P" / "im.png", make_image(40, 30, 2));  // the user's own
  write_image(tmp / "ph" / "a.jpg", make_image(40, 30, 3));
  write_image(tmp / "ph" / "a.png", make_image(40, 30, 4));  // the user's own
  const std::string p_im = read_file(tmp / "P" / "im.png"), ph_a = read_file(tmp / "ph" / "a.png");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"P/wet", "P"}, {"P/wet", "P", "--shard", "0/2"}, {"P/wet", "P", "--shard", "1/2"},
        {"ph/a.jpg", "out.jpg", "--mask-dir", "ph"}}) {
    const RunResult r = remove(args);
    SCOPED_TRACE(r.command);
    EXPECT_EQ(r.code, 2) << r.describe();
    EXPECT_NE(r.err.find("already exists"), std::string::npos) << r.describe();
  }
  EXPECT_EQ(read_file(tmp / "P" / "im.png"), p_im);
  EXPECT_EQ(read_file(tmp / "ph" / "a.png"), ph_a);
  EXPECT_FALSE(fs::exists(tmp / "out.jpg"));
  // Two inputs whose masks are one file are refused by every shard, not only by the shard
  // that holds both.
  write_image(tmp / "Q" / "x.png", make_image(40, 30, 5));
  write_image(tmp / "Q" / "x.jpg", make_image(40, 30, 6));
  for (const char* shard : {"0/3", "1/3", "2/3"}) {
    const RunResult r = remove({"Q", "Qo", "--mask-dir", "Qm", "--shard", shard});
    SCOPED_TRACE(r.command);
    EXPECT_EQ(r.code, 2) << r.describe();
    EXPECT_NE(r.err.find("(of 'Q/x.jpg')"), std::string::npos) << "names both inputs\n" << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "Qm"));
  }
}

// A run stopped while writing leaves a hidden temporary beside its output; the next run into
// that folder removes it, and only it: not a temporary whose writer still runs (another shard,
// here this test's own process), not a user's file that only looks like one, and not a young
// one whose process id is free here (its writer may run on another host or in another
// container that shares the folder: ids are per machine and PID namespace).
TEST_F(RemoveCli, ARunRemovesTheTemporariesOfAStoppedOne) {
  write_image(tmp / "in" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "in" / "b.png", make_image(40, 30, 2));
  fs::create_directories(tmp / "out");
  const std::string live = ".a.png.tmp-" + std::to_string(::getpid()) + "-0";
  const std::string stale = ".a.png.tmp-4194303-7", young = ".b.png.tmp-4194303-8";
  for (const std::string& name : {stale, young, live, std::string(".notes.tmp-keep")})
    write_file(tmp / "out" / name, "x");
  const auto old = fs::file_time_type::clock::now() - std::chrono::minutes(10);
  for (const std::string& name : {stale, live, std::string(".notes.tmp-keep")}) fs::last_write_time(tmp / "out" / name, old);
  const RunResult r = remove({"in", "out", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "out" / stale));
  EXPECT_TRUE(fs::exists(tmp / "out" / young)) << "a young temporary of a process that is not here was removed";
  EXPECT_TRUE(fs::exists(tmp / "out" / live));
  EXPECT_TRUE(fs::exists(tmp / "out" / ".notes.tmp-keep"));
  EXPECT_TRUE(fs::exists(tmp / "out" / "b.png"));
}

// A photograph's colour profile (a wide-gamut phone photograph's, say) is given to its output,
// PNG or JPEG, so that it keeps its colours in a colour-managed viewer; the mask gets none.
TEST_F(RemoveCli, TheOutputKeepsTheInputsColourProfile) {
  const std::string icc = testsupport::test_icc_profile("RGB ", 300);
  raindrop::write_image_atomic(make_image(64, 48, 1), tmp / "photo.jpg", raindrop::kDefaultPngLevel, icc);
  for (const char* out : {"out.png", "out.jpg"}) {
    const RunResult r = remove({"photo.jpg", out, "--mask", "mask.png", "-q"});
    ASSERT_EQ(r.code, 0) << r.describe();
    std::string read;
    raindrop::read_image_native(tmp / out, 1, &read);
    EXPECT_EQ(read, icc) << out;
    raindrop::read_image_native(tmp / "mask.png", 1, &read);
    EXPECT_EQ(read, "") << "the mask is no photograph";
  }
}

// A link to a folder inside the input folder is not followed (it may lead back up the tree),
// and not silently: a warning says its images are not processed.
TEST_F(RemoveCli, ALinkedFolderIsNotFollowedSilently) {
  write_image(tmp / "in" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "elsewhere" / "b.png", make_image(40, 30, 2));
  fs::create_directory_symlink(tmp / "elsewhere", tmp / "in" / "linked");
  const RunResult r = remove({"in", "out", "-q"});
  ASSERT_EQ(r.code, 0) << r.describe();
  EXPECT_NE(r.err.find("not following 1 symbolic link to folders under 'in' (first: 'in/linked')"), std::string::npos)
      << r.describe();
  EXPECT_TRUE(fs::exists(tmp / "out" / "a.png"));
  EXPECT_FALSE(fs::exists(tmp / "out" / "linked"));
}

// Any two of input, output, mask and contact sheet naming one file (or, in folder mode, the
// mask folder being the input or output folder) would overwrite one with another: refused as
// a usage error before anything is read or written.
TEST_F(RemoveCli, CoincidingPathsAreRefused) {
  write_image(tmp / "batch" / "a.png", make_image(40, 30, 1));
  write_image(tmp / "batch" / "sub" / "b.png", make_image(17, 33, 2));
  fs::create_directories(tmp / "results");
  write_image(tmp / "results" / "a.png", make_image(40, 30, 3));  // an earlier run's output
  const auto before = std::vector<std::string>{read_file(tmp / "in.png"), read_file(tmp / "batch" / "a.png"),
                                               read_file(tmp / "batch" / "sub" / "b.png"), read_file(tmp / "results" / "a.png")};
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"in.png", "in.png"}, {"in.png", "./in.png"}, {"./in.png", "sub/../in.png"},
        {"in.png", "out.png", "--mask", "in.png"}, {"in.png", "out.png", "--mask", "./out.png"},
        {"in.png", "out.png", "--contact-sheet", "in.png"}, {"in.png", "out.png", "--contact-sheet", "out.png"},
        {"in.png", "out.png", "--mask", "m.png", "--contact-sheet", "./m.png"}, {"in.png", "out.png", "--mask-dir", "."},
        {"batch", "results", "--mask-dir", "batch"}, {"batch", "results", "--mask-dir", "./results/"},
        {"batch", "results", "--mask", "batch/"}, {"batch", "results", "--contact-sheet", "batch/a.png"},
        {"batch", "results", "--contact-sheet", "results/sub/b.png"}}) {
    fs::create_directories(tmp / "sub");
    const RunResult r = remove(args);
    SCOPED_TRACE(r.command);
    EXPECT_EQ(r.code, 2) << r.describe();
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << r.describe();
    EXPECT_EQ(lines[0].rfind(kErrorPrefix, 0), 0u) << r.describe();
    EXPECT_NE(lines[0].find("are the same"), std::string::npos) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
    EXPECT_FALSE(fs::exists(tmp / "m.png"));
    EXPECT_FALSE(fs::exists(tmp / "results" / "sub")) << "nothing written";
    EXPECT_EQ(before, (std::vector<std::string>{read_file(tmp / "in.png"), read_file(tmp / "batch" / "a.png"),
                                                read_file(tmp / "batch" / "sub" / "b.png"),
                                                read_file(tmp / "results" / "a.png")}))
        << "a file was overwritten";
    EXPECT_TRUE(hidden_temporaries(tmp.path()).empty());
  }
}


// Every destination (output, mask, contact sheet) is checked before the first write: a mask
// or sheet that cannot be written must not leave the output behind.
TEST_F(RemoveCli, BadMaskOrSheetLeavesNoOutput) {
  fs::create_directories(tmp / "adir");
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"in.png", "out.png", "--mask", "m.xyz"}, {"in.png", "out.png", "--mask", "adir"},
        {"in.png", "out.png", "--contact-sheet", "s.xyz"}, {"in.png", "out.png", "--contact-sheet", "adir"},
        {"in.png", "out.png", "--mask", "mask.png", "--contact-sheet", "s.xyz"}}) {
    SCOPED_TRACE(args.back());
    // A --mask name without an image extension is a usage error (exit 2); the rest fail at the writer.
    expect_clean_failure(remove(args), args.back(), args.size() == 4 && args[2] == "--mask" ? 2 : 1);
  }
  // A mask file in a format that cannot hold 0 and 255 in one channel: refused before the
  // removal (JPEG wrote other levels; WebP failed after the networks had run).
  for (const char* name : {"m.jpg", "m.JPEG", "m.webp", "m.exr"}) {
    SCOPED_TRACE(name);
    // A usage error (exit 2), as the README says of a bad command line.
    expect_clean_failure(remove({"in.png", "out.png", "--mask", name}), "name a .png, .tif or .bmp file", 2);
  }
  for (const char* name : {"m.tif", "m.BMP"}) {
    const RunResult r = remove({"in.png", "out.png", "--mask", name, "-q"});
    ASSERT_EQ(r.code, 0) << name << "\n" << r.describe();
    const auto m = read_image(tmp / name);
    ASSERT_TRUE(m);
    EXPECT_EQ(m->pixels.channels(), 1) << name;
    fs::remove(tmp / "out.png");
  }
  // Folder mode: no output at all when the sheet cannot be written.
  write_image(tmp / "batch" / "a.png", make_image(40, 30, 1));
  const RunResult r = remove({"batch", "results", "-q", "--contact-sheet", "sheet.xyz"});
  EXPECT_EQ(r.code, 1) << r.describe();
  EXPECT_NE(r.err.find("sheet.xyz"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "results" / "a.png")) << "output written before the sheet was found unwritable";
}

// A folder that not even root may write into: /proc takes no new files. For root the
// destination checks cannot see that (access() says it is writable), so this holds the writing
// itself to leave nothing behind: the output, mask and sheet appear together or not at all.
// (Run as another user, the checks refuse /proc first; the staging is then tested only as root,
// which is how this project's machines and its fresh-machine check run.)
TEST_F(RemoveCli, MaskOrSheetThatEvenRootCannotWriteLeavesNoOutput) {
  if (!fs::is_directory("/proc/self")) GTEST_SKIP() << "no /proc here";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"in.png", "out.png", "--mask", "/proc/raindrop-test-mask.png"},
        {"in.png", "out.png", "--contact-sheet", "/proc/raindrop-test-sheet.png"},
        {"in.png", "out.png", "--mask", "m.png", "--contact-sheet", "/proc/raindrop-test-sheet.png"}}) {
    SCOPED_TRACE(args.back());
    expect_clean_failure(remove(args), args.back());
    EXPECT_FALSE(fs::exists(tmp / "m.png"));
  }
}

TEST_F(RemoveCli, ReadOnlyFolderForMaskOrSheetLeavesNoOutput) {
  if (::geteuid() == 0) GTEST_SKIP() << "running as root, who may write into read-only folders (MaskOrSheetThatEvenRootCannotWriteLeavesNoOutput covers root; ReadOnlyFileIsKeptEvenByRoot the files)";
  fs::create_directories(tmp / "ro");
  fs::permissions(tmp / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"in.png", "out.png", "--mask", "ro/m.png"}, {"in.png", "out.png", "--contact-sheet", "ro/s.png"}}) {
    SCOPED_TRACE(args.back());
    expect_clean_failure(remove(args), args.back());
  }
  fs::permissions(tmp / "ro", fs::perms::owner_all);
}

// A file made read-only (chmod a-w) is not replaced, whoever runs the program: as output, mask
// or sheet, alone or in a folder run. Root passes access() for every file, and the write
// replaces the file by a rename, which needs only the folder's permission: without the check
// on the file's mode, root's run lost it silently.
TEST_F(RemoveCli, ReadOnlyFileIsKeptEvenByRoot) {
  write_file(tmp / "locked.png", "mine");
  fs::permissions(tmp / "locked.png", fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  fs::create_directories(tmp / "batch");
  write_image(tmp / "batch" / "a.png", make_image(64, 48, 1));
  fs::create_directories(tmp / "results");
  write_file(tmp / "results" / "a.png", "mine");
  fs::permissions(tmp / "results" / "a.png", fs::perms::owner_read);
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"in.png", "locked.png"}, {"in.png", "out.png", "--mask", "locked.png"},
        {"in.png", "out.png", "--contact-sheet", "locked.png"}, {"batch", "results", "-q"}}) {
    SCOPED_TRACE(args[1] + " " + args.back());
    const RunResult r = remove(args);
    EXPECT_EQ(r.code, 1) << r.describe();
    EXPECT_NE(r.err.find("read-only"), std::string::npos) << r.describe();
    EXPECT_EQ(read_file(tmp / "locked.png"), "mine");
    EXPECT_EQ(read_file(tmp / "results" / "a.png"), "mine");
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
  }
  // Writable again, it is replaced as any output is.
  fs::permissions(tmp / "locked.png", fs::perms::owner_write, fs::perm_options::add);
  ASSERT_EQ(remove({"in.png", "locked.png"}).code, 0);
  EXPECT_NE(read_file(tmp / "locked.png"), "mine");
}


// libjpeg only warns at a premature end of file and fills the missing rows with grey; that
// decode is incomplete and must be an error, whatever the cut.
TEST_F(RemoveCli, TruncatedJpeg) {
  write_image(tmp / "whole.jpg", make_image(480, 360, 4));
  const std::string bytes = read_file(tmp / "whole.jpg");
  ASSERT_GT(bytes.size(), 4000u);
  for (size_t cut : {size_t{1000}, bytes.size() / 2, bytes.size() - 2}) {
    SCOPED_TRACE(cut);
    write_file(tmp / "cut.jpg", bytes.substr(0, cut));
    expect_clean_failure(remove({"cut.jpg", "out.png", "--mask", "mask.png"}), "cut.jpg");
  }
  ASSERT_EQ(remove({"whole.jpg", "out.png"}).code, 0) << "the whole file decodes";
}


// A phone photograph stored on its side, with an EXIF Orientation that says "turn a quarter
// clockwise to show": the networks see it upright, and the output and mask are written upright
// (no tag needed), the same bytes as for a PNG of the upright pixels.
TEST_F(RemoveCli, JpegOrientationIsAppliedBeforeRemoval) {
  write_image(tmp / "stored.jpg", make_image(61, 43, 3));
  const std::string jpeg = read_file(tmp / "stored.jpg");
  // APP1: "Exif\0\0", a big-endian TIFF header, one IFD entry: Orientation (0x0112), SHORT, 1, 6.
  const std::string payload = std::string("Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01\0\x06\0\0\0\0\0\0", 32);
  const std::string app1 = std::string("\xff\xe1\0", 3) + static_cast<char>(payload.size() + 2) + payload;
  write_file(tmp / "side.jpg", jpeg.substr(0, 2) + app1 + jpeg.substr(2));
  const cv::Mat upright = raindrop::read_image_native(tmp / "side.jpg");
  ASSERT_EQ(upright.cols, 43);
  ASSERT_EQ(upright.rows, 61);
  write_image(tmp / "upright.png", upright);
  ASSERT_EQ(remove({"side.jpg", "a.png", "--mask", "a-mask.png"}).code, 0);
  ASSERT_EQ(remove({"upright.png", "b.png", "--mask", "b-mask.png"}).code, 0);
  EXPECT_EQ(read_file(tmp / "a.png"), read_file(tmp / "b.png"));
  EXPECT_EQ(read_file(tmp / "a-mask.png"), read_file(tmp / "b-mask.png"));
  const auto out = read_image(tmp / "a.png");
  ASSERT_TRUE(out);
  EXPECT_EQ(out->width, 43);
  EXPECT_EQ(out->height, 61);
}

// libpng prints its own "libpng error: ..." line on stderr before OpenImageIO reports the
// error: malformed image data must be caught first, so that the user sees one line, ours.
TEST_F(RemoveCli, CorruptPngDataIsOneLine) {
  const auto chunks = png_chunks(read_file(tmp / "in.png"));
  std::string idat;
  for (const auto& [type, data] : chunks) {
    if (type == "IDAT") idat += data;
  }
  std::string raw(43 * (1 + 61 * 3), '\0');  // one filter byte and 61 RGB pixels per row
  uLongf raw_size = raw.size();
  ASSERT_EQ(::uncompress(reinterpret_cast<Bytef*>(raw.data()), &raw_size,
                         reinterpret_cast<const Bytef*>(idat.data()), idat.size()), Z_OK);
  ASSERT_EQ(raw_size, raw.size());
  auto deflate = [](const std::string& bytes) {
    std::string out(::compressBound(bytes.size()), '\0');
    uLongf n = out.size();
    EXPECT_EQ(::compress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(bytes.data()),
                         bytes.size()), Z_OK);
    out.resize(n);
    return out;
  };
  // The PNG with its image data replaced (header and the other chunks kept).
  auto with_idat = [&](const std::string& data) {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& c : chunks) {
      if (c.first == "IDAT") {
        if (out.back().first != "IDAT") out.emplace_back("IDAT", data);
      } else {
        out.push_back(c);
      }
    }
    return png_from_chunks(out);
  };
  std::string bad_stream = idat;
  for (size_t i = bad_stream.size() / 2; i < bad_stream.size() / 2 + 16; ++i) bad_stream[i] ^= 0x5a;
  std::string bad_filter = raw;
  bad_filter[raw.size() / 2 / (1 + 61 * 3) * (1 + 61 * 3)] = 9;  // a row's filter type: 0-4 only
  auto bad_ihdr = chunks;
  bad_ihdr[0].second[8] = 3;  // bit depth 3
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"short_idat.png", with_idat(deflate(raw.substr(0, raw.size() / 2)))},
      {"cut_stream.png", with_idat(idat.substr(0, idat.size() / 2))},
      {"bad_zlib.png", with_idat(bad_stream)},
      {"bad_filter.png", with_idat(deflate(bad_filter))},
      {"bad_ihdr.png", png_from_chunks(bad_ihdr)},
  };
  for (const auto& [name, bytes] : cases) {
    SCOPED_TRACE(name);
    write_file(tmp / name, bytes);
    expect_clean_failure(remove({name, "out.png", "--mask", "mask.png"}), name);
  }
  ASSERT_EQ(remove({"in.png", "out.png"}).code, 0) << "the original decodes";
}


// An overlap whose double does not fit an int was taken as a small one and ended in an
// OpenCV assertion (exit 1); it is a bad command line.
TEST_F(RemoveCli, HugeTileOverlapIsAUsageError) {
  for (const char* overlap : {"1073741824", "2147483647"}) {
    const RunResult r = remove({"in.png", "out.png", "--tile", "64", "--tile-overlap", overlap});
    EXPECT_EQ(r.code, 2) << r.describe();
    EXPECT_NE(r.err.find("--tile-overlap " + std::string(overlap) + " must be less than half of --tile 64"),
              std::string::npos) << r.describe();
    EXPECT_FALSE(fs::exists(tmp / "out.png"));
  }
}


// More threads than cores only adds contention (-j 1024 took minutes on a 480x360 image):
// capped at the cores, with one line saying so.
TEST_F(RemoveCli, ThreadsAreCappedAtTheCores) {
  const unsigned cores = std::thread::hardware_concurrency();
  if (cores == 0 || cores >= 1024) GTEST_SKIP() << "this machine reports " << cores << " cores";
  const auto start = std::chrono::steady_clock::now();
  const RunResult r = remove({"in.png", "out.png", "-j", "1024"});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.code, 0) << r.describe();
  const auto lines = split_lines(r.err);
  ASSERT_EQ(lines.size(), 1u) << r.describe();
  EXPECT_EQ(lines[0], "raindrop-remove: warning: -j 1024 is more than the " + std::to_string(cores) +
                          " cores of this machine; using " + std::to_string(cores))
      << r.describe();
  EXPECT_LT(seconds, 60.0) << "a 61x43 image";
  EXPECT_TRUE(read_image(tmp / "out.png"));
}


// Folder mode removes two images at once where there are two threads (--workers, each image
// on its share of them): every output, mask and the contact sheet are the bytes of one image at
// a time on the same threads per image, and the sheet keeps the inputs' order.
TEST_F(RemoveCli, WorkersGiveTheBytesOfOneImageAtATime) {
  const char* names[] = {"a.png", "b.png", "c.png", "d.png", "e.png", "f.png"};
  for (int i = 0; i < 6; ++i) write_image(tmp / "batch" / names[i], make_image(30 + 7 * i, 41 - 3 * i, 10 + i));
  const RunResult one = remove({"batch", "one", "--mask-dir", "one-masks", "--contact-sheet", "one.png", "-j", "1",
                                "--workers", "1", "-q"});
  ASSERT_EQ(one.code, 0) << one.describe();
  const RunResult two = remove({"batch", "two", "--mask-dir", "two-masks", "--contact-sheet", "two.png", "-j", "2",
                                "--workers", "2", "-q", "--time"});
  ASSERT_EQ(two.code, 0) << two.describe();
  EXPECT_NE(two.err.find("2 threads, 2 images at once"), std::string::npos) << two.describe();
  for (const char* n : names) {
    SCOPED_TRACE(n);
    EXPECT_EQ(read_file(tmp / "two" / n), read_file(tmp / "one" / n));
    EXPECT_EQ(read_file(tmp / "two-masks" / n), read_file(tmp / "one-masks" / n));
  }
  EXPECT_EQ(read_file(tmp / "two.png"), read_file(tmp / "one.png")) << "the sheet: the first four images, in order";
  // More workers than threads: capped, with one line saying so.
  const RunResult many = remove({"batch", "many", "-j", "1", "--workers", "3", "-q"});
  ASSERT_EQ(many.code, 0) << many.describe();
  EXPECT_EQ(many.err, "raindrop-remove: warning: --workers 3 is more than the 1 threads; using 1\n") << many.describe();
  EXPECT_EQ(read_file(tmp / "many" / "f.png"), read_file(tmp / "one" / "f.png"));
  EXPECT_EQ(remove({"batch", "bad", "--workers", "-1"}).code, 2);
  EXPECT_FALSE(fs::exists(tmp / "bad"));
}

// Files whose pixel data is damaged (chunks and CRCs intact, so the header check before the
// models load passes them) fail inside a worker while the other removes its neighbour. Without
// --keep-going the run stops with exit 1 and one line naming the first failed image in the
// inputs' order, the damaged ones leave nothing, and no image starts once the failure is known
// (img0 and img1 start together, img1 fails at its decode while the larger img0 is still being
// removed: nothing after img1 is written). With it, every other image is written and the
// failures are reported in the inputs' order.
TEST_F(RemoveCli, WorkersStopAtAFailureOrGoOn) {
  write_image(tmp / "batch" / "img0.png", make_image(320, 240, 20));
  for (int i = 1; i < 6; ++i) write_image(tmp / "batch" / ("img" + std::to_string(i) + ".png"), make_image(40, 30, 20 + i));
  for (const char* name : {"img1.png", "img4.png"}) {
    auto chunks = png_chunks(read_file(tmp / "batch" / name));
    for (auto& [type, data] : chunks) {
      if (type != "IDAT") continue;
      for (size_t i = data.size() / 2; i < data.size() / 2 + 16 && i < data.size(); ++i) data[i] ^= 0x5a;
    }
    write_file(tmp / "batch" / name, png_from_chunks(chunks));
  }
  RunResult r = remove({"batch", "stop", "-j", "2", "--workers", "2", "-q"});
  EXPECT_EQ(r.code, 1) << r.describe();
  ASSERT_EQ(split_lines(r.err).size(), 1u) << r.describe();
  EXPECT_NE(r.err.find("cannot decode"), std::string::npos) << "a failure in a worker, not the header check\n" << r.describe();
  EXPECT_NE(r.err.find("img1.png"), std::string::npos) << r.describe();
  EXPECT_FALSE(fs::exists(tmp / "stop" / "img1.png"));
  for (int i = 2; i < 6; ++i) EXPECT_FALSE(fs::exists(tmp / "stop" / ("img" + std::to_string(i) + ".png"))) << i;
  EXPECT_TRUE(hidden_temporaries(tmp / "stop").empty());
  r = remove({"batch", "go", "-j", "2", "--workers", "2", "-q", "--keep-going"});
  EXPECT_EQ(r.code, 3) << r.describe();
  for (int i : {0, 2, 3, 5}) EXPECT_TRUE(fs::exists(tmp / "go" / ("img" + std::to_string(i) + ".png"))) << i;
  EXPECT_FALSE(fs::exists(tmp / "go" / "img1.png"));
  EXPECT_FALSE(fs::exists(tmp / "go" / "img4.png"));
  EXPECT_NE(r.err.find("4 of 6 images done, 2 failed"), std::string::npos) << r.describe();
  const size_t first = r.err.find("img1.png"), second = r.err.find("img4.png");
  ASSERT_NE(first, std::string::npos) << r.describe();
  ASSERT_NE(second, std::string::npos) << r.describe();
  EXPECT_LT(first, second) << "failures reported in the inputs' order\n" << r.describe();
}


// NaN passes CLI11's range check (every comparison with it is false); it is a bad command
// line like any other out-of-range threshold, found before the models are loaded.
TEST_F(RemoveCli, NanThresholdIsAUsageError) {
  for (const char* option :
       {"--threshold", "--large-drop-growth", "--large-drop-sharpness", "--large-drop-detail", "--surround-fill-mad"}) {
    for (const char* value : {"nan", "NaN", "-nan"}) {
      const RunResult r = remove({"in.png", "out.png", option, value, "--models", "no-such-models"});
      EXPECT_EQ(r.code, 2) << r.describe();
      EXPECT_NE(r.err.find(option), std::string::npos) << r.describe();
      EXPECT_EQ(r.err.find("no-such-models"), std::string::npos) << "checked before loading models\n" << r.describe();
      EXPECT_FALSE(fs::exists(tmp / "out.png"));
    }
  }
}

}  // namespace
}  // namespace removetest
