// Colour visualisations of masks in the seed paper's colours (its Fig. 7 and 8):
//   boom left cyan, boom right blue, overlap of both green (combined boom image);
//   receiver red (dark red (128,0,0) where in the boom's shadow, mask bit kMaskShadow), boom over
//   receiver white (left) / magenta (right);
//   stereo classes (its Fig. 2): visible to both red, neither green, left only cyan, right only blue.
// Outputs are RGB8 images the size of the masks.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.hpp"

namespace augrig {

Image visualize_boom_overlap(const Image& mask_left, const Image& mask_right);  // Fig. 7b
Image visualize_receiver_occlusion(const Image& mask, bool left_camera);        // Fig. 8a / 8b
Image visualize_stereo_classes(const std::vector<std::uint8_t>& classes, int width, int height);
// Darkened copy of `background` (any format, debayered) with a mask visualisation blended over it.
Image blend_over(const Image& background, const Image& visualization, float alpha = 0.6f);

// Any supported format -> RGB8 (Bayer is demosaiced, Mono8 replicated).
Image to_rgb8(const Image& image);

}  // namespace augrig
