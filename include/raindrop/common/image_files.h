#pragma once
// Which files are images, and finding them in folders: one rule for raindrop-render's and
// raindrop-remove's folder inputs, so that a folder one program accepts the other does too.
#include <filesystem>
#include <string>
#include <vector>

namespace raindrop {

// The file's extension in lower case, with its dot (".png"; "" without one).
std::string lowercase_extension(const std::filesystem::path& p);

// A known image extension (any case): how a file named on the command line is told from a
// list of files.
bool has_image_extension(const std::filesystem::path& p);

// An image found in a folder: a known extension and not hidden (".name": our own
// temporaries, editors' and file managers' files).
bool is_image_name(const std::filesystem::path& p);

// The known extensions for messages: "bmp, exr, jpeg, jpg, png, tif, tiff, webp".
std::string image_extensions();

// A path compared as a place on disk: absolute and canonical as far as it exists, so that
// "./a", "a" and "sub/../a" are one, and so are "dir/" and "dir".
std::filesystem::path canonical_form(const std::filesystem::path& p);
// Whether `p` is the folder `dir` or lies under it (in canonical form).
bool is_under(const std::filesystem::path& p, const std::filesystem::path& dir);
// Whether `p` lies under the folder `dir` and is not `dir` itself.
bool strictly_inside(const std::filesystem::path& p, const std::filesystem::path& dir);

// Image files in `dir` (recursively or not), sorted, each as `dir / relative name` (lexically:
// a symbolic link keeps its own name). Folders in `skip` that lie strictly inside `dir` (and
// what lies under them) are left out: an output folder inside the input folder, whose files
// are not inputs; a skip folder that is `dir` or holds it leaves nothing out. Throws
// raindrop::Error if `dir` cannot be listed. Symbolic links to folders are not followed (a link
// may lead back up the tree): with `unfollowed`, they are listed there, for a warning.
std::vector<std::filesystem::path> list_image_files(const std::filesystem::path& dir, bool recursive,
                                                    const std::vector<std::filesystem::path>& skip = {},
                                                    std::vector<std::filesystem::path>* unfollowed = nullptr);

}  // namespace raindrop
