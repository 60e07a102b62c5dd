#pragma once
// Finding the frames to render.
//  - Cityscapes: <root>/leftImg8bit/<split>/<city>/<city>_<seq>_<frame>_leftImg8bit.png, with
//    the calibration in <root>/camera/<split>/<city>/<city>_<seq>_<frame>_camera.json when
//    present (intrinsic fx, fy, u0, v0 at the file's resolution).
//  - Anything else: an image file, a folder (searched recursively for image files), or a
//    text file listing one image path per line (relative paths are relative to the list).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "raindrop/render/camera.h"

namespace raindrop {

struct InputImage {
  std::filesystem::path path;
  std::string id;     // file-name-safe and unique within a run
  std::string split;  // "train", "val", "test" for Cityscapes, else "none"
  std::optional<Camera> calibration;  // at the file's native size; width/height unset (0)
};

// split: "train", "val", "test" or "all". Throws raindrop::Error if the layout is missing.
std::vector<InputImage> find_cityscapes(const std::filesystem::path& root, const std::string& split);

// `skip`: folders whose files are not inputs when walking a folder (those strictly inside it):
// the output folder and the folders a render writes into, so that a run into a folder inside
// its input folder, or into the input folder itself, does not take its own outputs as inputs.
std::vector<InputImage> find_images(const std::filesystem::path& file_folder_or_list,
                                    const std::vector<std::filesystem::path>& skip = {});

// Intrinsics from a Cityscapes camera JSON. Throws raindrop::Error if malformed.
Camera read_cityscapes_camera(const std::filesystem::path& json_path);

// Throws raindrop::Error if two inputs share an id.
void check_unique_ids(const std::vector<InputImage>& inputs);

}  // namespace raindrop
