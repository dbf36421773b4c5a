// dejag/app: image sequences on disk — a folder of images, a folder written by dejag render, or a
// printf-style numbered pattern (frame_%04d.exr) — as dejag filter and dejag metrics read them.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace dejag::cli {

// .png, .jpg/.jpeg, .tif/.tiff or .exr (any case).
bool isImageFile(const std::filesystem::path& path);
// "frame_%04d.png" -> the path of frame i (isPattern has checked the pattern).
std::string formatPattern(const std::string& pattern, int index);
// True for a printf-style sequence pattern: one field %d, %Nd or %0Nd with N at most 2 digits, in the
// file name. Throws dejag::Error for a '%' that is not such a field.
bool isPattern(const std::string& path);
// The frame numbers of a pattern that exist, in order: the files of its folder whose names it gives.
std::vector<int> sequenceFrames(const std::string& pattern);
// The number at the end of a file's stem ("frame_0012.exr" -> 12), or -1.
long trailingNumber(const std::filesystem::path& path);
// A folder written by dejag render: it holds render.json next to its frame_NNNN.exr files.
bool isRenderFolder(const std::filesystem::path& folder);

// One frame of a sequence: its file and its number (-1 if its name has none).
struct SequenceFrame {
    std::string path;
    long number = -1;
};
// The frames of a pattern (every number that exists; a gap is an error naming the missing frame) or a
// folder (its images in name order, hidden files left out; a dejag render folder's frame_NNNN.exr only).
// Throws dejag::Error when there is none.
std::vector<SequenceFrame> listSequence(const std::string& patternOrFolder);
// True when `path` names a sequence (a pattern or a folder) rather than one file.
bool isSequence(const std::string& path);

}  // namespace dejag::cli
