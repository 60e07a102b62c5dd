// raindrop-remove: removes adherent raindrops from photographs with the three networks of
// Hao et al. (ICCV-W 2019), run through ONNX Runtime (docs/CONTRACTS.md section 2).
//
//   raindrop-remove in.png out.png [options]        one image
//   raindrop-remove in_folder/ out_folder/ [options] every image under in_folder (recursive),
//                                                    written to out_folder with the same
//                                                    relative names (masks: --mask-dir DIR)
//
// The output keeps the input's size, channel count and bit depth (8/16-bit grey, grey+alpha,
// RGB, RGBA; alpha is copied through) where the output format can hold them, else a warning
// (warn_format_loss). Models are found without flags (see model_paths.h):
// --models DIR, else $RAINDROP_MODELS, else <prefix>/share/raindrop/models/<name>, else the
// source tree's models/<name>; <name> from --model-config or models/DEFAULT.
//
// Exit codes: 0 success; 1 error (bad input, bad model, unwritable output: one line on
// stderr, no partial output file); 2 bad command line; 3 batch run with --keep-going
// finished but some inputs failed.
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <future>
#include <iostream>
#include <map>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <chrono>
#include <thread>
#include <vector>

#include <signal.h>

#include <CLI/CLI.hpp>
#include <opencv2/imgproc.hpp>

#include "options.h"
#include "own_outputs.h"
#include "raindrop/common/contact_sheet.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"
#include "raindrop/common/image_io.h"
#include "raindrop/common/progress.h"
#include "raindrop/common/shard.h"
#include "raindrop/common/version.h"
#include "raindrop/remove/int8_precision.h"
#include "raindrop/remove/model_paths.h"
#include "raindrop/remove/remover.h"

namespace fs = std::filesystem;
using namespace raindrop;
using namespace raindrop::removal;
using raindrop::cli::is_own_output;
using raindrop::cli::record_own_output;
using raindrop::cli::kOwnOutputsList;
using raindrop::cli::read_own_outputs;

namespace {

constexpr int kSheetRows = 4;  // images on a batch run's contact sheet
// Folders with an image larger than this go one image at a time unless --workers says
// otherwise: each image's working memory grows with its pixels (an 11-megapixel photograph
// peaks near 0.4 GB), and two at once must not turn a folder that fits into one that does not.
constexpr std::int64_t kTwoAtATimeMaxPixels = std::int64_t{1} << 24;
constexpr int kPanelWidth = 512;

// A command line that is well-formed but asks for something impossible (exit code 2, like
// CLI11's own errors), found after parsing.
class UsageError : public Error {
 public:
  using Error::Error;
};

// Image files under `dir`, recursively, sorted, relative to `dir`; files under the `skip`
// folders (the output and mask folders, when they lie inside the input folder) are left out.
std::vector<fs::path> list_images(const fs::path& dir, const std::vector<fs::path>& skip) {
  std::vector<fs::path> unfollowed;
  std::vector<fs::path> files = list_image_files(dir, true, skip, &unfollowed);
  // Not followed (a link may lead back up the tree), and not silently: their images are not inputs.
  if (!unfollowed.empty())
    std::fprintf(stderr,
                 "raindrop-remove: warning: not following %zu symbolic link%s to folders under '%s' (first: '%s'): "
                 "the images behind them are not processed (give such a folder as an input of its own)\n",
                 unfollowed.size(), unfollowed.size() == 1 ? "" : "s", dir.string().c_str(),
                 unfollowed.front().string().c_str());
  // EXR holds float images, which this program does not take (read_image_native): a folder's
  // EXR files are not inputs here, as before image_files.h gave both programs one list.
  files.erase(std::remove_if(files.begin(), files.end(),
                             [](const fs::path& f) { return lowercase_extension(f) == ".exr"; }),
              files.end());
  // Lexically: fs::relative resolves symbolic links, which put a linked input's output
  // beside its target ("out/../elsewhere/a.png") instead of under the output folder.
  for (auto& f : files) f = f.lexically_relative(dir);
  return files;
}

// An 8-bit RGB view of any image we handle, for the contact sheet (alpha dropped).
cv::Mat sheet_panel(const cv::Mat& img) {
  cv::Mat rgb = to_rgb8(img);
  // Keep the sheet's memory small in batch runs: panels are shown kPanelWidth wide anyway.
  if (rgb.cols > kPanelWidth) {
    cv::Mat small;
    const int h = std::max(1, static_cast<int>(std::lround(static_cast<double>(rgb.rows) * kPanelWidth / rgb.cols)));
    cv::resize(rgb, small, {kPanelWidth, h}, 0, 0, cv::INTER_AREA);
    return small;
  }
  // Kept for the sheet: a panel that is still the image's own buffer (8-bit RGB) is copied.
  return rgb.data == img.data ? rgb.clone() : rgb;
}

struct Job {
  fs::path input, output;
  std::optional<fs::path> mask;
  std::string caption;
  bool make_dirs = false;  // folder mode: create the output's sub-folders
  std::string shard_key;   // folder mode: the input's name relative to the input folder (shard.h)
};

// Whether the folder `outer` holds `inner` (at any depth, not being it): by name, and by
// identity (device and inode) for every folder above `inner`, so that the same folder reached
// through a bind mount or another link counts too.
bool holds_by_identity(const fs::path& outer, const fs::path& inner) {
  if (outer.empty() || inner.empty()) return false;
  if (strictly_inside(inner, outer)) return true;
  std::error_code ec;
  if (!fs::is_directory(outer, ec)) return false;
  const fs::path start = fs::weakly_canonical(fs::absolute(inner, ec), ec);
  for (fs::path p = start.parent_path(); !p.empty(); p = p.parent_path()) {
    std::error_code e;
    if (fs::equivalent(p, outer, e) && !e) return !fs::equivalent(start, outer, e);
    if (p == p.root_path()) break;
  }
  return false;
}

// Refuses a run in which two of the places it reads and writes are one: the later write
// would silently replace the input (or an earlier output). Paths are compared canonically,
// so "./a.png", "a.png" and "sub/../a.png" are the same file.
struct Place {
  std::string role;
  fs::path path;
  fs::path of;  // the input a written file comes from (named in the message), or empty
};

void refuse_coinciding(const std::vector<Place>& places, const char* kind) {
  std::map<fs::path, const Place*> seen;
  const auto said = [](const Place& p) {
    return "the " + p.role + " '" + p.path.string() + "'" + (p.of.empty() ? "" : " (of '" + p.of.string() + "')");
  };
  for (const auto& place : places) {
    if (place.path.empty()) continue;
    auto [it, fresh] = seen.emplace(canonical_form(place.path), &place);
    if (!fresh)
      throw UsageError(said(*it->second) + " and " + said(place) + " are the same " + kind + "; choose another one");
  }
}

// The output keeps the input's depth and channels when its format can hold them; writing a
// 16-bit RGBA image as .jpg is allowed (the user chose the extension), but not silently. Said
// once a run, on one line: in folder mode every output has its input's format anyway.
void warn_format_loss(const fs::path& file, const std::string& lost) {
  static bool said = false;
  if (lost.empty() || said) return;
  said = true;
  std::fprintf(stderr, "raindrop-remove: warning: '%s': %s (write .png or .tif to keep it whole)\n",
               file.string().c_str(), lost.c_str());
}

// Temporaries an earlier run left beside this run's outputs when it was stopped (its process
// gone: a run still going, another shard say, keeps its own). Only names this program gives
// them, for the files this run writes. A process id names a process only on its own machine
// and in its own PID namespace: a run on another host or in another container writing into the
// same shared folder has an id that is free here. So a temporary is also left alone while it is
// young (kStaleTemporaryAge since its last write): a writer anywhere writes one image's file in
// seconds, and an abandoned one is removed by a later run.
constexpr auto kStaleTemporaryAge = std::chrono::minutes(2);

void remove_stale_temporaries(const std::vector<Job>& jobs) {
  std::map<fs::path, std::set<std::string>> stems;  // folder -> stems of the files written there
  for (const auto& j : jobs) {
    for (const fs::path* p : {&j.output, j.mask ? &*j.mask : nullptr}) {
      if (p) stems[p->has_parent_path() ? p->parent_path() : fs::path(".")].insert(temporary_stem(p->filename().string()));
    }
  }
  std::error_code ec;
  for (const auto& [dir, names] : stems) {
    for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
      const auto temporary = parse_temporary_name(it->path().filename().string());
      if (!temporary || !names.count(temporary->stem)) continue;
      if (::kill(static_cast<pid_t>(temporary->pid), 0) == 0 || errno != ESRCH) continue;  // its writer still runs
      std::error_code age_ec;
      const auto written = fs::last_write_time(it->path(), age_ec);
      if (age_ec || fs::file_time_type::clock::now() - written < kStaleTemporaryAge) continue;  // maybe a writer elsewhere
      std::error_code ignored;
      fs::remove(it->path(), ignored);
    }
    ec.clear();
  }
}

struct Settings {
  RemoveOptions options;
  bool time = false;
  bool quiet = false;
  bool batch = false;
  // Images the wet gate judged dry (their outputs are their inputs), counted for the summary.
  std::atomic<std::size_t>* judged_dry = nullptr;
};

// An input image decoded, with its colour profile (given to the output: image_io.h).
struct DecodedInput {
  cv::Mat image;
  std::string icc_profile;
};

DecodedInput decode_input(const fs::path& path) {
  DecodedInput d;
  d.image = read_image_native(path, 1, &d.icc_profile);
  return d;
}

// Whether `output`'s format loses pixels (JPEG, WebP): what a dry frame written there is not.
bool is_lossy_output(const fs::path& output) {
  const std::string e = lowercase_extension(output);
  return e == ".jpg" || e == ".jpeg" || e == ".jpe" || e == ".webp";
}

// Removes the drops from one file, staging its output and mask in `files` (the caller commits
// them, then says what the output's format lost: `lost`); returns the panels for the contact
// sheet. `decoded`, if given, is the file being decoded already (its error is thrown here).
std::vector<cv::Mat> process(Remover& remover, const Job& job, const Settings& s, bool want_panels,
                             StagedImages* files, std::string* lost, std::future<DecodedInput>* decoded = nullptr) {
  DecodedInput in = decoded ? decoded->get() : decode_input(job.input);
  const cv::Mat input = in.image;
  const std::string& icc_profile = in.icc_profile;
  const auto started = std::chrono::steady_clock::now();
  RemoveResult r = remover.run(input, s.options);
  const double run_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
  if (job.make_dirs) {
    for (const fs::path* p : {&job.output, job.mask ? &*job.mask : nullptr}) {
      std::error_code ec;
      if (p && p->has_parent_path() && !fs::create_directories(p->parent_path(), ec) && ec)
        throw Error("cannot create the folder '" + p->parent_path().string() + "' (" + ec.message() + ")");
    }
  }
  // A dry frame (--wet-gate) is its pixels as read, written losslessly where the format is; a
  // JPEG written as a JPEG is the input file's bytes (encoding it again would change it), unless
  // those bytes cannot be checked against the pixels (a CMYK JPEG): then it is encoded again.
  bool reencoded = false;
  if (r.judged_dry() && files->stage_jpeg_as_it_was(job.input, input, job.output)) {
    lost->clear();
  } else {
    *lost = files->stage(r.image, job.output, kDefaultPngLevel, icc_profile);
    reencoded = r.judged_dry() && is_lossy_output(job.output);
  }
  if (job.mask) files->stage(r.mask, *job.mask);
  if (r.judged_dry()) {
    if (s.judged_dry) ++*s.judged_dry;
    // A single image's output that is its input needs saying; a folder run counts them.
    if (!s.batch && !s.quiet && !s.time)
      std::fprintf(stderr, "raindrop-remove: %s: judged dry by the wet gate (z %+.2f): %s\n", job.input.string().c_str(),
                   *r.wet_gate_score,
                   reencoded ? "its pixels as read, encoded again (a lossy format)" : "the output is the input as it was");
  }
  if (s.time) {
    const double coverage = 100.0 * cv::countNonZero(r.mask) / static_cast<double>(r.mask.total());
    char coarse[160] = "", sharp[64] = "", filled[64] = "";
    // Regions left to the working-scale pass because they were too sharp (--large-drop-sharpness):
    // named, so that a user can tell why a large drop was not replaced.
    if (r.sharp_large_drops > 0)
      std::snprintf(sharp, sizeof sharp, " (%d more left alone: too sharp)", r.sharp_large_drops);
    if (r.coarse_scale > 0)
      std::snprintf(coarse, sizeof coarse, ", %d large drop%s%s at scale %.3g", r.large_drops, r.large_drops == 1 ? "" : "s",
                    sharp, r.coarse_scale);
    // Parts of the mask filled from their surroundings instead of by the 3RN (--surround-fill-area).
    if (s.options.surround_fill_area.value_or(1) > 0)
      std::snprintf(filled, sizeof filled, ", %d small drop%s filled from the surround", r.surround_filled,
                    r.surround_filled == 1 ? "" : "s");
    // The fine pass's drops (--fine-drops), where it ran.
    char fine[96] = "";
    if (r.fine_scale > 0)
      std::snprintf(fine, sizeof fine, ", %d fine drop%s filled at scale %.3g", r.fine_drops, r.fine_drops == 1 ? "" : "s",
                    r.fine_scale);
    // Which detector decided the mask, where the models have a router (--no-router: none).
    char routed[160] = "";
    if (r.router_score)
      std::snprintf(routed, sizeof routed, ", detector %s (router z %+.2f)",
                    r.alternative_detector() ? ("'" + remover.router()->alternative + "'").c_str() : "the models' own",
                    *r.router_score);
    // The wet gate's judgement (--wet-gate): a dry image's output is its input.
    char gated[96] = "";
    if (r.wet_gate_score)
      std::snprintf(gated, sizeof gated, ", wet gate z %+.2f: %s", *r.wet_gate_score,
                    r.judged_dry() ? "dry, left as read" : "wet");
    // The stages' sum counts side-by-side work twice; the wall time of the removal (decoding and
    // writing the files not included) is what the image cost.
    std::fprintf(stderr, "raindrop-remove: %s: %dx%d at scale %.3g%s%s%s%s%s, %d tile%s, mask %.2f%%: %s; removal %.1f ms wall\n",
                 job.input.string().c_str(), input.cols, input.rows, r.scale, gated, routed, filled, coarse, fine, r.tiles_x * r.tiles_y,
                 r.tiles_x * r.tiles_y == 1 ? "" : "s", coverage, r.times.describe().c_str(), run_ms);
  }
  if (!want_panels) return {};
  return {sheet_panel(input), sheet_panel(r.mask), sheet_panel(r.image)};
}

// The run is over and every file it wrote is in place: exit at once. Destroying the sessions
// would free ONNX Runtime's memory and stop its threads one by one, about 10 ms of a 1280x720
// photograph's 0.23 s, which the kernel does anyway when the process ends. With
// AddressSanitizer it returns `code` instead, so that the run ends normally and the leak check
// sees everything.
int exit_without_teardown(int code) {
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
#if !defined(__SANITIZE_ADDRESS__)
  std::_Exit(code);
#endif
  return code;
}

int run(int argc, char** argv) {
  CLI::App app{"raindrop-remove: removes adherent raindrops from images (Hao et al., ICCV-W 2019:\n"
               "detection, region reconstruction and refinement networks, run with ONNX Runtime).\n"
               "IN and OUT are two image files, or two folders (every image under IN, recursively,\n"
               "is written to OUT under the same relative name)."};
  app.footer(
      "Models: --models DIR, else $RAINDROP_MODELS, else <prefix>/share/raindrop/models/<name>, else the source\n"
      "tree's models/<name>; <name> is --model-config or what models/DEFAULT names: its first line, or on a CPU\n"
      "with VNNI its int8 copy (the line 'vnni NAME'; 1.3x faster there, 0.05 dB lower on average).\n"
      "Inputs: 8/16-bit grey, grey+alpha, RGB, RGBA up to 2^26 pixels (e.g. 8192x8192); the output keeps size,\n"
      "channels and depth (grey: the networks see it as RGB, the output is its luma 0.299R+0.587G+0.114B; alpha\n"
      "is copied). An EXIF/TIFF orientation is applied: phone photographs are processed and written upright.\n"
      "A PNG or JPEG input's ICC colour profile (a valid one of at most 1 MiB) goes into a PNG or JPEG output; other metadata (EXIF) does not.\n"
      "Existing output files are replaced, except in an output or mask folder that holds the input or lies\n"
      "inside it: there only files an earlier run wrote and nobody changed since (its hidden .raindrop-remove-outputs).\n"
      "A read-only file (chmod a-w) is never replaced, also not by root: the run stops before writing.\n"
      "Exit codes: 0 success; 1 error (one line on stderr, no partial output); 2 bad command line;\n"
      "3 folder run with --keep-going finished but some images failed.");
  std::string input, output, models_dir, model_config, large_drop_models, mask, mask_dir, sheet, shard_text, wet_gate_file;
  Device device = Device::cpu;
  GraphOpt graph_opt = GraphOpt::all;
  std::optional<double> threshold, scale;
  std::optional<int> dilation;
  std::optional<double> large_drop_growth;
  double large_drop_sharpness = kLargeDropMaxSharpness;
  double large_drop_detail = kLargeDropDetail;
  std::optional<int> surround_fill_area;
  double surround_fill_mad = kSurroundFillMad;
  int surround_fill_rim = kSurroundFillRim;
  int threads = 0, workers = 0, tile = kDefaultTile, overlap = kDefaultOverlap;
  bool time = false, quiet = false, keep_going = false, no_large_drops = false, mirror_average = false, fine_drops = false,
       keep_outside_mask = false;
  bool no_router = false;
  Shard shard;
  app.add_option("input", input, "Input image, or folder of images")->required();
  app.add_option("output", output, "Output image (format from the extension), or folder")->required();
  app.add_option("--models", models_dir, "Model folder with rdn.onnx, rrn.onnx, rfn.onnx (default: see below)");
  app.add_option("--model-config", model_config, "Model configuration name, e.g. compact or paper (default: models/DEFAULT)");
  auto* mask_opt =
      app.add_option("--mask", mask, "Also write the final mask (0/255, after dilation) here: a .png, .tif or .bmp file; a folder in folder mode");
  app.add_option("--mask-dir", mask_dir, "Also write the masks into this folder, as <relative name>.png (either mode)")
      ->excludes(mask_opt);
  app.add_option("--threshold", threshold, "Detection threshold on the RDN probability (default: the models')")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--dilation", dilation, "Mask dilation size k (elliptical k x k; 1: none; default: the models', 3 for the committed ones). 7 takes out more of a photograph's drop rims and halos, and costs 0.2-0.4 dB on rendered drops, whose masks are exact (docs/RESULTS.md 4.51)")
      ->check(CLI::Range(1, kMaxDilation));
  auto* scale_opt = app.add_option("--scale", scale,
                 "Scale the networks see the image at, in (0, 1] (default: the image's long side brought to the models' "
                 "working size, 512 for the committed models; never enlarged). Outside the mask the output is the input")
      ->check(CLI::Range(0.0, 1.0));
  auto* large_opt = app.add_option("--large-drop-models", large_drop_models,
                 "Model folder (rrn.onnx and rfn.onnx) whose 3RN and RFN reconstruct the drops the coarse pass finds "
                 "large (default: the configuration the models' LARGE_DROPS file names, else the models themselves; "
                 "give the models' own folder to use them throughout)");
  auto* growth_opt =
      app.add_option("--large-drop-growth", large_drop_growth,
                     "In the coarse pass, dilate each drop's mask by the odd size nearest this fraction of its diameter "
                     "(the disk of its area), at least the models' k: large drops' defocused edges spread past what the "
                     "detector finds; 0: k for every drop (default: the models', 0.35 for the default)")
          ->check(CLI::Range(0.0, kMaxLargeDropGrowth));
  auto* sharpness_opt =
      app.add_option("--large-drop-sharpness", large_drop_sharpness,
                     "In the coarse pass, replace a large region only where the image there is this smooth or smoother: "
                     "the mean absolute Laplacian of its luma at the working scale, in 8-bit levels (defocused drops are "
                     "smooth; clusters of sharp windshield drops and sharp scenery are not, and the coarse fill would blur "
                     "them); inf: every large region")
          ->capture_default_str()
          ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  auto* detail_opt =
      app.add_option("--large-drop-detail", large_drop_detail,
                     "Where the coarse pass's fill replaces the image, add back this fraction of the input's fine detail "
                     "(the input minus its Gaussian blur of 3 px at the working scale), in proportion to the fill's weight: "
                     "a defocused drop is semi-transparent, so the scene's detail shows through it, and the fill, made at a "
                     "third of the working scale, has none (it smeared buildings and lettering on photographs); 0: the fill "
                     "alone (docs/RESULTS.md 4.77)")
          ->capture_default_str()
          ->check(CLI::Range(0.0, 1.0));
  app.add_flag("--no-large-drops", no_large_drops,
               "Skip the coarse pass at a third of that scale that takes over drops too large for the networks there "
               "(mask regions with the area of a disk 60 px across at the working scale, clusters included, e.g. on a "
               "lens cover)")
      ->excludes(large_opt)
      ->excludes(growth_opt)
      ->excludes(sharpness_opt)
      ->excludes(detail_opt);
  app.add_flag("--no-router", no_router,
               "Always use the models' own detector: ignore the ROUTER file in their folder, which sends each image "
               "(at the automatic working scale) to the detector it suits, e.g. sharp windshield drops to "
               "compact-windshield's");
  app.add_option("--surround-fill-area", surround_fill_area,
                 "Fill parts of the mask of at most this many pixels (at the scale that brings the long side to 512; "
                 "scaled with --scale) from their surroundings "
                 "(push-pull interpolation) instead of by the 3RN, where those surroundings are smooth "
                 "(--surround-fill-mad): the 3RN leaves faint rims of small sharp drops on sky, walls and roads; "
                 "0: the 3RN everywhere (default: the detector's own, 150 for the default's, 1500 for "
                 "compact-windshield's, which the router gives windshield photographs)")
      ->check(CLI::Range(0, std::numeric_limits<int>::max()));
  app.add_option("--surround-fill-mad", surround_fill_mad,
                 "How smooth a part's surroundings must be for --surround-fill-area: the median absolute deviation of "
                 "their luma from its median, in 8-bit levels (the pixels outside the mask within 4 px of the part's "
                 "bounding box)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  app.add_option("--surround-fill-rim", surround_fill_rim,
                 "Grow each part --surround-fill-area fills into its rim first, by up to this many pixels (at the "
                 "scale that brings the long side to 512; scaled with --scale): the pixels just outside the mask more "
                 "than 12 levels of luma off its surroundings, where that structure ends within the reach (the dark "
                 "rims and bright halos real drops show past the detector's mask, not a pole or an edge); 0: off "
                 "(docs/RESULTS.md 4.54)")
      ->capture_default_str()
      ->check(CLI::Range(0, kMaxSurroundFillRim));
  app.add_flag("--mirror-average", mirror_average,
               "Also at the working scale, run the 3RN and RFN on the image and on its mirror image and average the two "
               "(the coarse pass for large drops always does): about twice the time of the networks' pass, for "
               "+0.15-0.18 dB on the paper preset's drops, up to +0.04 on thin-lens renders and +0.01 on real ones "
               "(docs/RESULTS.md 4.11)");
  app.add_flag("--keep-outside-mask", keep_outside_mask,
               "Images the networks see at full size (long side at most 512 without --scale, or --scale 1): keep the "
               "input's own pixels outside the mask, as larger images always do, instead of the refinement network's "
               "output everywhere (the paper's pipeline, which changed street frames without drops by up to about 30 "
               "levels far from any detection): +0.3 dB on held-out sparse rendered drops at 512x256, the same "
               "elsewhere (docs/RESULTS.md 4.70)");
  app.add_option("--wet-gate", wet_gate_file,
                 "A camera's wet gate (python -m raindrop_tools.wet_gate fit, on that camera's own frames labelled wet "
                 "or dry): an image it judges dry from the detector's maps is left as it was (its pixels as read; a JPEG "
                 "written as a JPEG: the input file's bytes), with an empty mask. For "
                 "cameras whose dry frames the detector marks (overexposed sky through a lens cover: 39% of such frames "
                 "marked and smeared without it); fitted for one camera, wrong for others (docs/RESULTS.md 4.72)")
      ->excludes(scale_opt);
  app.add_flag("--fine-drops", fine_drops,
               "After both passes, run the detector again at 1.5 times the working scale and fill the small drops it "
               "finds over smooth surroundings (sky, walls, road) from them: the tiny sharp drops of windshield and "
               "glass photographs the working scale misses. Costs a detector run on 2.25 times the working pixels "
               "(docs/RESULTS.md 4.45); images the networks see at full size (long side at most 512 without --scale) "
               "are unchanged; --surround-fill-area does not apply to it");
  app.add_option("-j,--threads", threads, "CPU threads (0: one per core; more than the cores: capped, with a warning); with 2 or more, RDN and 3RN run side by side on half each (folders: of each image's worker's share, --workers)")
      ->capture_default_str()->check(CLI::Range(0, 1024));
  app.add_option("--workers", workers,
                 "Folder mode: images removed at once, each on its share of --threads (0: two where there are two or "
                 "more threads and images and none is over 16 megapixels, else one; at most --threads). The same "
                 "output bytes as one at a time, more images per second: one image's stages leave cores idle "
                 "(docs/RESULTS.md 4.59)")
      ->capture_default_str()->check(CLI::Range(0, 1024));
  app.add_option("--device", device, "Execution device")->transform(cli::names_to(device_names()))->default_str("cpu");
  app.add_option("--tile", tile, "Process images larger than N x N in overlapping tiles of at most N x N (0: never)")
      ->capture_default_str();
  app.add_option("--tile-overlap", overlap,
                 "Smallest overlap between tiles, in pixels (seamless when >= 4x the networks' receptive radius: 28 px for the paper's)")
      ->capture_default_str();
  app.add_option("--graph-opt", graph_opt, "ONNX Runtime graph optimisation level")
      ->transform(cli::names_to(graph_opt_names()))->default_str("all");
  app.add_flag("--time", time, "Print per-stage timings on stderr");
  app.add_option("--contact-sheet", sheet, "Also write an input | mask | output PNG (folder mode: the first images)");
  app.add_flag("--keep-going", keep_going, "Folder mode: go on after an image fails (exit code 3)");
  app.add_option("--shard", shard_text,
                 "Folder mode: process only shard K of N (0 <= K < N, e.g. $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT): "
                 "the images whose relative name hashes to K");
  app.add_flag("-q,--quiet", quiet, "No progress bar");
  app.set_version_flag("--version", std::string("raindrop-remove ") + kVersion + " (" + ort_description() +
                                        "; int8 models: " + int8_kernels_description() + "; " + onnxruntime_telemetry_state() + ")");
  try {
    app.parse(argc, argv);
    // An option given an empty value would read as not given (--mask "" wrote no mask, --models ""
    // took the default models, --shard "" ran every image, --wet-gate "" ran without a gate): refused.
    if (const auto name = cli::option_given_empty(app, {"--mask", "--mask-dir", "--contact-sheet", "--shard", "--models",
                                                         "--model-config", "--large-drop-models", "--wet-gate"}))
      throw Error(*name + " needs a value, got ''");
    // NaN passes CLI::Range (every comparison with it is false).
    if (threshold && std::isnan(*threshold)) throw Error("--threshold: nan is not a number between 0 and 1");
    if (large_drop_growth && std::isnan(*large_drop_growth))
      throw Error("--large-drop-growth: nan is not a number between 0 and " +
                  std::to_string(static_cast<int>(kMaxLargeDropGrowth)));
    if (std::isnan(large_drop_sharpness)) throw Error("--large-drop-sharpness: nan is not a number >= 0");
    if (std::isnan(large_drop_detail)) throw Error("--large-drop-detail: nan is not a number between 0 and 1");
    if (std::isnan(surround_fill_mad)) throw Error("--surround-fill-mad: nan is not a number >= 0");
    if (scale && !(*scale > 0.0)) throw Error("--scale must be a number in (0, 1]");
    check_tile_options(tile, overlap);
    if (!shard_text.empty()) shard = parse_shard(shard_text);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const Error& e) {
    std::cerr << "raindrop-remove: " << one_line(e.what()) << "\nRun with --help for more information.\n";
    return 2;
  }

  // More threads than cores only adds contention: ONNX Runtime's spinning workers made
  // -j 1024 take minutes on a small image.
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (threads > cores) {
    std::fprintf(stderr, "raindrop-remove: warning: -j %d is more than the %d cores of this machine; using %d\n", threads,
                 cores, cores);
    threads = cores;
  }
  const int all_threads = threads > 0 ? threads : cores;

  // Check the inputs before loading the models (which takes a moment).
  std::error_code ec;
  const fs::path in_path(input), out_arg(output);
  if (!fs::exists(in_path, ec)) throw Error("'" + input + "': no such file or folder");
  const bool batch = fs::is_directory(in_path, ec);
  if (!batch && !shard_text.empty()) throw UsageError("--shard splits a folder run; '" + input + "' is a file");

  std::vector<Job> jobs;
  if (batch && mask_dir.empty()) std::swap(mask, mask_dir);  // folder mode: --mask is a folder
  if (batch) {
    if (fs::exists(out_arg, ec) && !fs::is_directory(out_arg, ec))
      throw Error("input '" + input + "' is a folder, so the output must be a folder too; '" + output + "' is a file");
    // Masks written into the input or output folder would replace the images there.
    refuse_coinciding({{"input folder", in_path, {}}, {"output folder", out_arg, {}}, {"mask folder", fs::path(mask_dir), {}}},
                      "folder");
    const auto images = list_images(in_path, {out_arg, fs::path(mask_dir)});
    if (images.empty()) throw Error("no image files (" + image_extensions() + "; exr not taken) under '" + input + "'");
    // Every image's job, this shard's or not: the checks below hold for the whole run, so that
    // no shard writes over another shard's input or output.
    for (const auto& rel : images) {
      Job j{in_path / rel, out_arg / rel, std::nullopt, rel.string(), true, rel.generic_string()};
      if (!mask_dir.empty()) j.mask = (fs::path(mask_dir) / rel).replace_extension(".png");
      jobs.push_back(j);
    }
  } else {
    fs::path out = out_arg;
    // "out/" names a folder: one that is not there is said so, not taken for a file without a format.
    if (!out.has_filename() && !fs::is_directory(out, ec)) throw Error("output folder '" + output + "' does not exist");
    if (fs::is_directory(out, ec)) out /= in_path.filename();
    Job j{in_path, out, std::nullopt, in_path.filename().string(), false, {}};
    if (!mask.empty()) {
      // A mask is 0 and 255 in one channel: JPEG wrote it with other levels (9 on a photograph),
      // WebP holds no single channel (refused only after the removal), GIF, HDR and others
      // change it. Only formats that keep it exactly are taken. Folder masks are PNG.
      const std::string ext = lowercase_extension(mask);
      if (ext != ".png" && ext != ".tif" && ext != ".tiff" && ext != ".bmp")
        throw UsageError("--mask '" + mask + "': a mask holds 0 and 255 in one channel; name a .png, .tif or .bmp file");
      j.mask = fs::path(mask);
    }
    if (!mask_dir.empty()) j.mask = (fs::path(mask_dir) / in_path.filename()).replace_extension(".png");
    jobs.push_back(j);
  }
  // Every name written, before any other check (the path comparisons below fail on a name
  // the file system refuses) and before the inference (after which it used to fail).
  for (const Job& j : jobs) {
    check_file_name_length(j.output);
    if (j.mask) check_file_name_length(*j.mask);
  }
  if (!sheet.empty()) check_file_name_length(sheet);
  // Every file read or written, once: no write may land on an input or on another output
  // (checked before anything is read or written, over every shard's files).
  {
    std::vector<Place> places;
    for (const auto& j : jobs) places.push_back({"input", j.input, {}});
    for (const auto& j : jobs) {
      places.push_back({"output", j.output, j.input});
      if (j.mask) places.push_back({"mask", *j.mask, j.input});
    }
    places.push_back({"contact sheet", fs::path(sheet), {}});
    refuse_coinciding(places, "file");
  }
  // Folders whose file names this program chooses (an output folder, a mask folder) and that
  // hold the input or lie inside it may hold the user's own photographs: there a run replaces
  // only what an earlier run wrote (own_outputs.h). A file named on the command line is the
  // user's choice and is replaced as asked.
  struct Guarded {
    std::string role;
    fs::path folder;
    bool holds = false;  // it holds the input (else it lies inside it)
    std::map<std::string, raindrop::cli::WrittenFile> own;  // what earlier runs wrote there
    // The file a job writes into this folder, if any.
    std::optional<fs::path> file_of(const Job& j) const { return role == "output" ? std::optional<fs::path>(j.output) : j.mask; }
  };
  std::vector<Guarded> guarded;
  const auto guard = [&](const std::string& role, const fs::path& folder) {
    if (holds_by_identity(folder, in_path)) {
      guarded.push_back({role, folder, true, {}});
    } else if (holds_by_identity(in_path, folder)) {
      guarded.push_back({role, folder, false, {}});
    }
  };
  if (batch || fs::is_directory(out_arg, ec)) guard("output", out_arg);
  if (!mask_dir.empty()) guard("mask", fs::path(mask_dir));
  for (auto& g : guarded) {
    g.own = read_own_outputs(g.folder);
    // Each file written there is appended to this list: one this run may not write would stop
    // it after its first output, so it is checked now, before any.
    // Anything but a plain file there (a folder, a link) would fail the first append, after the
    // first output was written.
    const fs::path list = g.folder / kOwnOutputsList;
    const fs::file_status list_status = fs::symlink_status(list, ec);
    if (fs::exists(list_status) && !fs::is_regular_file(list_status))
      throw Error("'" + list.string() + "' is not a plain file: this program lists the files it writes into '" +
                  g.folder.string() + "' there; move it");
    check_replaceable(list);
    for (const auto& j : jobs) {
      const std::optional<fs::path> file = g.file_of(j);
      if (!file) continue;
      // Anything there, a link that leads nowhere included, unless it is an unchanged own output.
      if (!fs::exists(fs::symlink_status(*file, ec)) ||
          is_own_output(g.own, file->lexically_relative(g.folder).generic_string(), *file))
        continue;
      throw UsageError("'" + file->string() + "' already exists in the " + g.role + " folder '" + g.folder.string() +
                       "', which " + (g.holds ? "holds" : "lies inside") + " the input '" + input +
                       "', and this run would replace it: that folder's " + kOwnOutputsList +
                       " does not list it as a file raindrop-remove wrote there, or it changed since; choose " +
                       (g.role == "output" ? "an " : "a ") + g.role +
                       " folder that neither holds nor lies inside the input, or move that file");
    }
  }
  if (batch) {
    std::vector<Job> owned;
    for (auto& j : jobs) {
      if (shard.owns(j.shard_key)) owned.push_back(std::move(j));  // another shard's otherwise (shard.h)
    }
    jobs = std::move(owned);
  }
  // Folder mode: every input's header is read before the models load and before the first
  // write, so that a file this program refuses (float, 5 channels, too large, not an image)
  // stops the run with nothing written, not after hours with part of the outputs there. Damage
  // inside the pixel data (a cut file) is still found only when the image is decoded. With
  // --keep-going such inputs are reported as failed at the end instead.
  std::vector<std::string> errors;
  std::int64_t largest_pixels = 0;
  if (batch) {
    std::vector<Job> readable;
    for (auto& j : jobs) {
      try {
        largest_pixels = std::max(largest_pixels, check_native_header(j.input));
        readable.push_back(std::move(j));
      } catch (const Error& e) {
        if (!keep_going) throw;
        errors.push_back(one_line(e.what()));
      }
    }
    jobs = std::move(readable);
  }
  // Every destination is checked before the (slow) inference and the first write, so that a
  // mask or sheet that cannot be written does not leave the output behind. In folder mode the
  // output and mask sub-folders are made as the run goes; the formats are the inputs'.
  if (!mask_dir.empty()) ensure_writable_dir(mask_dir);
  if (batch) ensure_writable_dir(out_arg);
  remove_stale_temporaries(jobs);
  std::set<std::string> checked_formats;
  for (const Job& j : jobs) {
    for (const fs::path* p : {&j.output, j.mask ? &*j.mask : nullptr}) {
      if (!p) continue;
      if (!batch || checked_formats.insert(p->extension().string()).second) {
        check_image_destination(*p, batch);
      } else {
        check_replaceable(*p);  // the rest of a folder run's files: not read-only
      }
    }
  }
  if (!sheet.empty()) check_image_destination(sheet);
  // One image: it is decoded on a thread of its own while ONNX Runtime and the models load,
  // which leaves a core idle for much of that time (the library's loading and set-up run on one
  // thread). Its errors are reported where reading it reported them, after the models'.
  std::future<DecodedInput> first_input;
  if (!batch && jobs.size() == 1) {
    try {
      first_input = std::async(std::launch::async, decode_input, jobs.front().input);
    } catch (const std::system_error&) {  // no thread to spare: it is read when its turn comes
    }
  }

  SessionConfig session;
  session.threads = threads;
  session.device = device;
  session.graph_opt = graph_opt;
  ModelSearch search = default_model_search();
  if (!models_dir.empty()) search.explicit_dir = fs::path(models_dir);
  if (!model_config.empty()) search.config = model_config;
  // DEFAULT's int8 copy is for CPUs that run int8 fast; on a GPU the float graphs run.
  if (device != Device::cpu) search.int8_fast = false;
  // Without the coarse pass the large-drop models are never needed: the models' own folder
  // stands in, so a LARGE_DROPS naming a folder that is not there does not stop the run.
  std::string model_choice;
  const fs::path model_dir = find_models(search, &model_choice);
  // A damaged gate is refused before the models load; whether it suits them, once they have.
  std::shared_ptr<const WetGate> wet_gate;
  if (!wet_gate_file.empty()) wet_gate = std::make_shared<const WetGate>(read_wet_gate(wet_gate_file));
  std::optional<fs::path> large_dir;
  if (no_large_drops) large_dir = model_dir;
  if (!large_drop_models.empty()) large_dir = fs::path(large_drop_models);
  // Folder mode removes `worker_count` images at once, each with its own models on its share
  // of the threads: one image's stages (decoding, the side-by-side networks of unequal length,
  // the blend, encoding) leave cores idle that another image's fill. Each image is removed
  // exactly as one at a time with the same threads per image.
  int worker_count = 1;
  if (batch && device == Device::cpu) {
    worker_count = workers > 0 ? workers : (all_threads >= 2 && largest_pixels <= kTwoAtATimeMaxPixels ? 2 : 1);
    if (worker_count > all_threads) {
      std::fprintf(stderr, "raindrop-remove: warning: --workers %d is more than the %d threads; using %d\n", worker_count,
                   all_threads, all_threads);
      worker_count = all_threads;
    }
    worker_count = std::max(1, std::min(worker_count, static_cast<int>(jobs.size())));
  } else if (workers > 1) {
    std::fprintf(stderr, "raindrop-remove: warning: --workers applies to folders on the CPU; one image at a time\n");
  }
  // The threads shared out, the first workers taking what does not divide evenly; the
  // workers' models load side by side.
  const auto make_remover = [&](int w) {
    SessionConfig mine = session;
    if (worker_count > 1) mine.threads = all_threads / worker_count + (w < all_threads % worker_count ? 1 : 0);
    return std::make_unique<Remover>(model_dir, mine, large_dir, !no_router);
  };
  std::vector<std::future<std::unique_ptr<Remover>>> loading;
  for (int w = 1; w < worker_count; ++w) loading.push_back(std::async(std::launch::async, make_remover, w));
  std::vector<std::unique_ptr<Remover>> removers;
  removers.push_back(make_remover(0));
  for (auto& f : loading) removers.push_back(f.get());
  Remover& remover = *removers.front();

  Settings s;
  s.options.threshold = threshold;
  s.options.dilation = dilation;
  s.options.large_drop_growth = large_drop_growth;
  s.options.large_drop_max_sharpness = large_drop_sharpness;
  s.options.large_drop_detail = large_drop_detail;
  s.options.tile = tile;
  s.options.overlap = overlap;
  s.options.scale = scale;
  s.options.large_drops = !no_large_drops;
  s.options.mirror_average = mirror_average;
  s.options.keep_outside_mask = keep_outside_mask;
  s.options.fine_drops = fine_drops;
  s.options.surround_fill_area = surround_fill_area;
  s.options.surround_fill_mad = surround_fill_mad;
  s.options.surround_fill_rim = surround_fill_rim;
  s.options.route = !no_router;
  if (wet_gate) check_wet_gate(*wet_gate, remover.model_dir(), remover.info());
  s.options.wet_gate = wet_gate;
  std::atomic<std::size_t> judged_dry{0};
  s.judged_dry = &judged_dry;
  s.quiet = quiet;
  s.batch = batch;
  s.time = time;
  if (time) {
    const ModelInfo& mi = remover.info();
    std::string thread_text = threads == 0 ? std::string("threads: one per core")
                                            : std::to_string(threads) + (threads == 1 ? " thread" : " threads");
    if (worker_count > 1) thread_text += ", " + std::to_string(worker_count) + " images at once";
    char sharpness_text[64] = "";  // the limit only matters when the coarse pass runs
    if (!no_large_drops) std::snprintf(sharpness_text, sizeof sharpness_text, ", large-drop sharpness %g", large_drop_sharpness);
    const std::string large = no_large_drops                           ? "no coarse pass"
                              : remover.large_drop_model_dir().empty() ? "large drops by the same models"
                                                                       : "large drops by '" + remover.large_drop_model_dir().string() + "'";
    const std::string routing = remover.router() ? "; router to the detector of '" + remover.alternative_detector_dir().string() + "'"
                                                 : "";
    std::fprintf(stderr,
                 "raindrop-remove: models '%s' (config %s%s, threshold %g, dilation %d, large-drop growth %g%s; %s%s), %s, "
                 "%s, %s\n",
                 remover.model_dir().string().c_str(), mi.config.c_str(),
                 model_choice.empty() ? "" : (" (" + model_choice + ")").c_str(), threshold.value_or(mi.threshold),
                 dilation.value_or(mi.dilation), no_large_drops ? 0.0 : large_drop_growth.value_or(mi.large_drop_growth),
                 sharpness_text, large.c_str(), routing.c_str(), ort_description().c_str(), to_string(device),
                 thread_text.c_str());
  }

  // A file written into a guarded folder is recorded there as written (own_outputs.h), so that
  // a later run may replace it while it is unchanged.
  // One that cannot be recorded (a full disk) is removed, as this run wrote it: left in place,
  // unlisted, it would make every later run into that folder refuse to start.
  // So is every later one of the image's (its mask after its output): none is left unlisted.
  const auto record_in_guarded = [&](const Job& j) {
    for (std::size_t k = 0; k < guarded.size(); ++k) {
      const std::optional<fs::path> file = guarded[k].file_of(j);
      if (!file) continue;
      try {
        record_own_output(guarded[k].folder, file->lexically_relative(guarded[k].folder).generic_string(), *file);
      } catch (const std::exception&) {
        for (std::size_t later = k; later < guarded.size(); ++later) {
          const std::optional<fs::path> unlisted = guarded[later].file_of(j);
          std::error_code removed;
          if (unlisted) fs::remove(*unlisted, removed);
        }
        throw;
      }
    }
  };
  const std::size_t refused = errors.size();
  Progress progress(static_cast<std::int64_t>(jobs.size()), "remove", batch && !quiet);
  // One image: its output, mask and contact sheet appear together or not at all (a sheet that
  // fails to write leaves no output). Folder mode: each image's output and mask together.
  StagedImages single;
  std::string single_lost;
  // The contact sheet holds the first kSheetRows images, in the inputs' order, that succeeded.
  std::map<std::size_t, std::vector<cv::Mat>> panels_of;
  std::mutex shared;  // guards panels_of, failed, failures, first_error, the own-output lists
  std::size_t next = 0, failures = 0;
  // Without --keep-going: the error of the failed image first in the inputs' order (a worker
  // may find its failure after another's later in the order).
  std::exception_ptr first_error;
  std::size_t first_error_at = 0;
  std::map<std::size_t, std::string> failed;  // with --keep-going: each failed image's error
  const auto stop_at = [&](std::size_t i, std::exception_ptr e) {
    if (!first_error || i < first_error_at) {
      first_error = std::move(e);
      first_error_at = i;
    }
  };
  const auto work = [&](Remover& mine) noexcept {
    // noexcept: nothing may leave a worker's thread; what no handler below takes ends the run
    // as before (std::terminate), on any thread.
    for (;;) {
      std::size_t i = 0;
      bool want_panels = false;
      {
        const std::lock_guard<std::mutex> lock(shared);
        // Without --keep-going the first failure ends the run (exit 1 through main): no image
        // starts once it is known; those other workers had begun are finished and kept.
        if (first_error || next == jobs.size()) return;
        i = next++;
        // Images that may still make the sheet: those below kSheetRows plus every one before
        // them that failed or may yet fail (at most one per worker in flight).
        want_panels = !sheet.empty() && i < kSheetRows + failures + removers.size();
      }
      const Job& job = jobs[i];
      try {
        StagedImages files;
        std::string lost;
        auto panels = process(mine, job, s, want_panels, batch ? &files : &single, batch ? &lost : &single_lost,
                              i == 0 && first_input.valid() ? &first_input : nullptr);
        files.commit();
        const std::lock_guard<std::mutex> lock(shared);
        if (batch) record_in_guarded(job);
        warn_format_loss(job.output, lost);
        if (want_panels) panels_of[i] = std::move(panels);
      } catch (const std::exception& e) {
        const std::lock_guard<std::mutex> lock(shared);
        ++failures;
        if (!batch || !keep_going) {
          stop_at(i, std::current_exception());
        } else {
          failed[i] = one_line(e.what());
        }
      } catch (...) {  // not ours: ends the run, as it did before there were workers
        const std::lock_guard<std::mutex> lock(shared);
        ++failures;
        stop_at(i, std::current_exception());
      }
      progress.advance();
    }
  };
  {
    std::vector<std::thread> others;
    for (std::size_t w = 1; w < removers.size(); ++w) {
      try {
        others.emplace_back(work, std::ref(*removers[w]));
      } catch (const std::system_error& e) {  // no more threads: the ones running take every image
        std::fprintf(stderr, "raindrop-remove: warning: %zu of %zu workers started (%s)\n", w, removers.size(), e.what());
        break;
      }
    }
    work(remover);
    for (auto& t : others) t.join();
  }
  if (first_error) std::rethrow_exception(first_error);
  for (auto& [i, e] : failed) errors.push_back(std::move(e));  // after the refused ones, in the inputs' order
  progress.finish();
  std::vector<std::vector<cv::Mat>> rows;
  std::vector<std::string> captions;
  for (auto& [i, panels] : panels_of) {
    if (static_cast<int>(rows.size()) == kSheetRows) break;
    rows.push_back(std::move(panels));
    captions.push_back(jobs[i].caption);
  }
  std::string sheet_error;  // folder mode with --keep-going: the sheet failed, after the images
  if (!sheet.empty() && !rows.empty()) {
    if (batch) {
      // The images are written: with --keep-going a sheet that cannot be made is one more
      // failure, reported with the images' (exit 3), not an error that hides them.
      try {
        write_image_atomic(make_contact_sheet(rows, {"input", "mask", "output"}, captions, kPanelWidth), sheet);
      } catch (const std::exception& e) {
        if (!keep_going) throw;
        sheet_error = one_line(e.what());
      }
    } else {
      single.stage(make_contact_sheet(rows, {"input", "mask", "output"}, captions, kPanelWidth), sheet);
    }
  }
  single.commit();
  if (!batch) record_in_guarded(jobs.front());
  if (!batch) warn_format_loss(jobs.front().output, single_lost);
  for (const auto& e : errors) std::cerr << "raindrop-remove: failed: " << e << "\n";
  if (!sheet_error.empty()) std::cerr << "raindrop-remove: failed: contact sheet " << sheet_error << "\n";
  if (batch && (!quiet || !errors.empty() || !sheet_error.empty())) {
    const std::string dry = wet_gate ? " (" + std::to_string(judged_dry.load()) + " judged dry by the wet gate: written as they were read)" : "";
    std::fprintf(stderr, "raindrop-remove: %zu of %zu images done%s, %zu failed; output in %s\n",
                 jobs.size() + refused - errors.size(), jobs.size() + refused, dry.c_str(), errors.size(), output.c_str());
  }
  return exit_without_teardown(errors.empty() && sheet_error.empty() ? 0 : 3);
}

}  // namespace

int main(int argc, char** argv) {
  // First, while this is the only thread: ONNX Runtime reads it when its environment is created.
  raindrop::removal::turn_off_onnxruntime_telemetry();
  try {
    return run(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << "raindrop-remove: error: " << one_line(e.what()) << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "raindrop-remove: error: " << one_line(e.what()) << "\n";
    return 1;
  }
}
