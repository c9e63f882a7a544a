#include "pipeline/frame_sink.hpp"

namespace augrig::pipeline {

void PairContext::make_whole() {
  if (made_whole || !result) return;
  make_whole_augmented(raw.left.image, result->left);
  make_whole_augmented(raw.right.image, result->right);
  made_whole = true;
}

}  // namespace augrig::pipeline
