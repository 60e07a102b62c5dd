#pragma once
// The EXIF Orientation tag of a JPEG, and the turn or mirror it asks for. Phones and many
// dashcams store the sensor's pixels as they were read out and say in this tag how to show
// them; every viewer, OpenCV's imread (and so the Python tools) among them, applies it. A
// program that ignores it processes the photograph on its side (drops and sky where the
// networks never saw them) and writes it out on its side. So JPEG files are read upright, as
// they are shown (jpeg_file.cpp), and so are the files the OpenImageIO plugin reads with an
// Orientation (src/oiio; PNG excepted); the written image needs no tag. Internal to
// raindrop_common, and compiled into the plugin.
#include <cstddef>

#include <opencv2/core.hpp>

namespace raindrop::exif {

// The Orientation (1-8) in the payload of an APP1 marker (after its length: "Exif\0\0", then
// the TIFF header and the first IFD); 0 when it holds no such tag, or anything in the way is
// malformed or out of range (the caller then looks at the next EXIF marker, or takes 1: as
// stored). Read as OpenCV and PIL read it: a SHORT or a LONG, its count not checked. Reads
// nothing outside [data, data + size).
int orientation(const unsigned char* data, std::size_t size);

// Whether an orientation swaps width and height (5-8: a quarter turn).
inline bool swaps_sides(int orientation) { return orientation >= 5 && orientation <= 8; }

// `image` made upright as OpenCV's imread does it for `orientation`: 2 mirrors left to right,
// 3 turns half round, 4 mirrors top to bottom, 5 transposes, 6 turns a quarter clockwise,
// 7 transposes the other way, 8 turns a quarter anticlockwise; 0, 1 and anything else: as it is.
void make_upright(cv::Mat& image, int orientation);

}  // namespace raindrop::exif
