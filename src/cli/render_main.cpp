// raindrop-render: renders adherent raindrops onto street images (Hao et al. 2019, section 3).
//
// Exit codes: 0 success; 1 error (bad input, unwritable output, bad scene: one line on
// stderr, nothing half-written); 2 bad command line; 3 --keep-going finished but some
// inputs failed.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "options.h"
#include "raindrop/common/contact_sheet.h"
#include "raindrop/common/error.h"
#include "raindrop/common/image_files.h"
#include "raindrop/common/image_io.h"
#include "raindrop/common/shard.h"
#include "raindrop/common/demo.h"
#include "raindrop/render/heap_tuning.h"
#include "raindrop/render/inputs.h"
#include "raindrop/render/render_job.h"
#include "raindrop/render/scene_config.h"

namespace fs = std::filesystem;
using namespace raindrop;

namespace {

std::optional<cv::Size> parse_size(const std::string& text) {
  if (text.empty() || text == "native") return std::nullopt;
  const auto size = cli::parse_width_height(text, 16, 16384);
  if (!size) throw Error("--size '" + text + "' must be WIDTHxHEIGHT between 16x16 and 16384x16384, e.g. 512x256");
  const int w = size->width, h = size->height;
  // The output is bounded like the input (image_io.h): a frame raindrop-remove and this
  // program would refuse to read back is not worth rendering.
  if (static_cast<std::int64_t>(w) * h > kMaxImagePixels)
    throw Error("--size '" + text + "' has " + std::to_string(static_cast<std::int64_t>(w) * h) +
                " pixels, more than the 2^26 (67 megapixels, e.g. 8192x8192) that both programs read");
  return cv::Size(w, h);
}

bool same_path(const fs::path& a, const fs::path& b) { return canonical_form(a) == canonical_form(b); }

// The contact sheet is written after the render: checked before it, so that it can neither
// replace an input or a rendered sample nor fail once the work is done. `samples`: the folders
// the render writes its images into, inside `out`.
void check_contact_sheet(const fs::path& sheet, const std::vector<InputImage>& inputs, const fs::path& out,
                         const std::vector<fs::path>& samples) {
  for (const InputImage& in : inputs) {
    if (!in.path.empty() && same_path(sheet, in.path))
      throw Error("the contact sheet '" + sheet.string() + "' is the input '" + in.path.string() + "'; choose another one");
  }
  const fs::path folder = sheet.has_parent_path() ? sheet.parent_path() : fs::path(".");
  for (const fs::path& s : samples) {
    if (same_path(folder, s))
      throw Error("the contact sheet '" + sheet.string() + "' would be written among the rendered samples in '" +
                  s.string() + "'; choose another folder");
  }
  if (same_path(sheet, out / "manifest.jsonl")) throw Error("the contact sheet '" + sheet.string() + "' is the manifest");
  // Its folder may be the output folder, made by the render.
  check_image_destination(sheet, same_path(folder, out));
}

// The demo's inputs: backgrounds drawn by the program, written as ordinary image files.
std::vector<InputImage> make_demo_inputs(const fs::path& out) {
  const fs::path dir = out / "backgrounds";
  ensure_writable_dir(dir);
  const std::pair<const char*, cv::Mat> images[] = {{"checkerboard", demo_checkerboard(1024, 512)},
                                                    {"street", demo_street(1024, 512)}};
  std::vector<InputImage> inputs;
  for (const auto& [name, img] : images) {
    const fs::path p = dir / (std::string(name) + ".png");
    write_image_atomic(img, p);
    inputs.push_back({p, name, "none", std::nullopt});
  }
  return inputs;
}

int run(int argc, char** argv) {
  CLI::App app{"raindrop-render: physically based adherent raindrops on street images.\n"
               "Renders rainy/clean/mask triplets and manifest.jsonl (docs/CONTRACTS.md).\n"
               "Without any input or --out it renders the built-in demo backgrounds into out/demo."};
  std::string cityscapes, split = "train", out = "out/render", scene_name = "paper", size_text, sheet, shard_text,
      merge_dir;
  std::vector<std::string> input_paths;
  int variants = 1, threads = 0, limit = 0, sheet_rows = 4;
  std::string png_level = png_level_name(kDefaultPngLevel);
  std::uint64_t seed = 0;
  bool demo = false, convert = false, keep_going = false, quiet = false, list_scenes = false, print_scene = false;
  auto* cityscapes_opt = app.add_option("--cityscapes", cityscapes, "Cityscapes root: walks leftImg8bit/<split>/<city>/*.png, reads camera/ intrinsics where present");
  app.add_option("--split", split, "Cityscapes split: train, val, test or all")
      ->capture_default_str()
      ->check(CLI::IsMember({"train", "val", "test", "all"}))
      ->needs(cityscapes_opt);
  app.add_option("-i,--input", input_paths, "Image file, folder (recursive) or list file; repeatable");
  app.add_flag("--demo", demo, "Render the built-in checkerboard and street backgrounds (the default when neither an input nor --out is given)");
  app.add_option("-o,--out", out, "Output folder")->capture_default_str();
  app.add_option("--variants", variants, "Rendered variants per input image")->capture_default_str()->check(CLI::Range(1, 1000));
  // Unsigned 64-bit: checked as text, since CLI11 wraps "-1" and clamps past 2^64 - 1 silently.
  app.add_option("--seed", seed, "Run seed (0 to 2^64 - 1); each sample derives its own")
      ->capture_default_str()
      ->check(cli::unsigned_64("seeds"));
  app.add_option("-j,--threads", threads, "Worker threads (0: all cores)")->capture_default_str()->check(CLI::Range(0, 1024));
  std::string presets;
  for (const auto& n : scene_preset_names()) presets += (presets.empty() ? "" : ", ") + n;
  app.add_option("--scene", scene_name, "Preset (" + presets + ") or JSON scene file")->capture_default_str();
  app.add_option("--size", size_text, "Output WIDTHxHEIGHT (centre-crop to the aspect, then resize), e.g. 512x256, or native; default: input size");
  app.add_option("--limit", limit, "Render only the first N inputs (0: all)")->check(CLI::Range(0, 100000000));
  app.add_option("--png-level", png_level,
                 "PNG compression: fast (Paeth rows deflated by libdeflate: fastest, about zlib level 3's size), "
                 "rle (zlib's run-length strategy: smaller than level 6 on photographs, about 2x slower than fast) "
                 "or a zlib level 0-9; a clean image that is its input PNG as it was (no --size change, 8-bit RGB, not interlaced, no EXIF orientation or animation, shown "
                 "as sRGB) is that file's bytes, not encoded again")
      ->capture_default_str()->check(CLI::IsMember({"fast", "rle", "0", "1", "2", "3", "4", "5", "6", "7", "8", "9"}));
  app.add_option("--shard", shard_text,
                 "Render only shard K of N (0 <= K < N, e.g. $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT): the "
                 "inputs whose id hashes to K (all their variants), into the shared output folder with manifest.part-K-of-N.jsonl");
  app.add_option("--merge-shards", merge_dir,
                 "Merge the manifest parts of a sharded run in this folder into its manifest.jsonl, then exit");
  app.add_flag("--convert", convert, "Accept 16-bit, grey and RGBA inputs by converting them to 8-bit RGB");
  app.add_flag("--keep-going", keep_going, "Render the remaining inputs after one fails (exit code 3)");
  app.add_option("--contact-sheet", sheet, "Write a clean | rainy | mask PNG of the first samples (default for the demo: <out>/contact_sheet.png)");
  app.add_option("--sheet-rows", sheet_rows, "Samples on the contact sheet")->capture_default_str()->check(CLI::Range(1, 64));
  app.add_flag("-q,--quiet", quiet, "No progress bar");
  app.add_flag("--list-scenes", list_scenes, "Print the preset names and exit");
  app.add_flag("--print-scene", print_scene, "Print the resolved scene as JSON and exit");
  app.set_version_flag("--version", "raindrop-render " + renderer_version());
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  Shard shard;
  std::optional<cv::Size> size;
  try {
    // An option given an empty value would read as not given: the demo rendered into ./out for
    // --merge-shards "", a whole run for --shard "".
    if (const auto name = cli::option_given_empty(app, {"--shard", "--merge-shards", "--contact-sheet", "--cityscapes", "--scene"}))
      throw Error(*name + " needs a value, got ''");
    size = parse_size(size_text);
    if (!shard_text.empty()) shard = parse_shard(shard_text);
    if (!merge_dir.empty() && (!cityscapes.empty() || !input_paths.empty() || demo || !shard_text.empty()))
      throw Error("--merge-shards only merges; give it no inputs and no --shard");
  } catch (const Error& e) {
    std::cerr << "raindrop-render: error: " << e.what() << "\n";
    return 2;
  }
  if (!merge_dir.empty()) {
    const std::int64_t n = merge_shards(merge_dir);
    std::fprintf(stderr, "raindrop-render: %lld samples in %s\n", static_cast<long long>(n),
                 (fs::path(merge_dir) / "manifest.jsonl").string().c_str());
    return 0;
  }

  if (list_scenes) {
    for (const auto& n : scene_preset_names()) std::cout << n << "\n";
    return 0;
  }
  RenderOptions options;
  options.scene = load_scene(scene_name);
  if (print_scene) {
    std::cout << scene_to_json(options.scene) << "\n";
    return 0;
  }
  options.out_dir = out;
  options.variants = variants;
  options.seed = seed;
  options.threads = threads;
  options.size = size;
  options.convert = convert;
  options.keep_going = keep_going;
  options.progress = !quiet;
  options.png_level = parse_png_level(png_level);
  options.shard = shard;

  std::vector<InputImage> inputs;
  if (!cityscapes.empty()) inputs = find_cityscapes(cityscapes, split);
  // The folders this run writes images into: never inputs, even when the output folder is the
  // input folder itself (then only these are left out of it).
  const std::vector<fs::path> written = {options.out_dir / "rainy", options.out_dir / "clean",
                                         options.out_dir / "mask", options.out_dir / "alpha"};
  std::vector<fs::path> skip = written;
  skip.push_back(options.out_dir);
  for (const auto& p : input_paths) {
    // A folder this run writes into is no input folder: a re-run would render its renders.
    for (const fs::path& w : written) {
      if (is_under(p, w))
        throw Error("the input '" + p + "' is in '" + w.string() + "', where this run writes its samples; choose another output folder");
    }
    auto more = find_images(p, skip);
    inputs.insert(inputs.end(), more.begin(), more.end());
  }
  // No input at all renders the demo into its own folder. Into a folder the user names, only
  // when asked (--demo): a forgotten --input once wrote the demo's backgrounds and samples into
  // the user's folder, and added them to a data set rendered there with the same settings.
  if (inputs.empty() && !demo) {
    if (app.get_option("--out")->count() > 0)
      throw Error("no input: give --input or --cityscapes (or --demo for the built-in backgrounds into '" +
                  options.out_dir.string() + "')");
    demo = true;
  }
  if (demo) {
    if (!cityscapes.empty() || !input_paths.empty()) throw Error("--demo renders its own backgrounds; drop --cityscapes/--input");
    // The demo's own default folder, unless the user named one (out/render included).
    if (app.get_option("--out")->count() == 0) options.out_dir = "out/demo";
    // Shards would all write the one default sheet.
    if (sheet.empty() && !shard.sharded()) sheet = (options.out_dir / "contact_sheet.png").string();
    if (!sheet.empty()) check_contact_sheet(sheet, {}, options.out_dir, written);  // before the backgrounds are written
    inputs = make_demo_inputs(options.out_dir);
  }
  if (sheet.empty() && app.count("--sheet-rows") > 0)
    throw Error("--sheet-rows sets the rows of a contact sheet: give --contact-sheet FILE too");
  // Against every input, the ones --limit leaves out included: they are the user's files too.
  if (!sheet.empty()) {
    options.contact_sheet_rows = sheet_rows;
    check_contact_sheet(sheet, inputs, options.out_dir, written);
  }
  if (limit > 0 && static_cast<int>(inputs.size()) > limit) inputs.resize(limit);

  const RenderSummary s = render_dataset(inputs, options);
  if (!s.errors.empty() && !keep_going) throw Error(s.errors.front());
  for (const auto& e : s.errors) std::cerr << "raindrop-render: failed: " << one_line(e) << "\n";

  if (!sheet.empty() && !s.samples.empty()) {
    std::vector<std::vector<cv::Mat>> rows;
    std::vector<std::string> captions;
    for (const auto& v : s.samples) {
      rows.push_back({v.clean, v.rainy, v.mask});
      captions.push_back(v.id);
    }
    write_image_atomic(make_contact_sheet(rows, {"clean", "rainy", "mask"}, captions, 512), sheet);
  }
  std::fprintf(stderr, "raindrop-render: %lld rendered, %lld already done, %lld failed in %.1f s",
               static_cast<long long>(s.rendered), static_cast<long long>(s.skipped), static_cast<long long>(s.failed),
               s.seconds);
  if (s.rendered > 0)
    std::fprintf(stderr, "; mean %.1f drops and %.2f%% of the frame covered per sample",
                 static_cast<double>(s.drops_sum) / s.rendered, 100.0 * s.coverage_sum / s.rendered);
  std::fprintf(stderr, "\nraindrop-render: data set in %s%s%s%s\n", options.out_dir.string().c_str(),
               shard.sharded() ? (" (shard " + shard.text() + ")").c_str() : "", sheet.empty() ? "" : ", contact sheet ",
               sheet.c_str());
  return s.failed > 0 ? 3 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  raindrop::keep_freed_frame_memory();  // before any thread starts (heap_tuning.h)
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "raindrop-render: error: " << one_line(e.what()) << "\n";
    return 1;
  }
}
