// look_compare: measurements that compare two images over a region (issue 33 §3). augrig inserts a
// rendered boom into boom-free frames ("augmented"); a simulator can render the same frames with
// the boom physically present ("physical"). A bench compares the two over the boom's footprint
// with these measurements. They know nothing of how either image was made: each takes images of
// augrig's formats and a region mask, and answers in DN (8-bit digital numbers) or pixels.
//
// Masks are Mono8 images of the frame's size; a nonzero pixel is in the region.
//
// What each measures, and why:
//   region_difference()   the mean and RMS of a - b: the brightness bias and the overall mismatch
//   robust_noise_sigma()  the noise level, so the augmented boom's grain can be held against the
//                         physical one's (Immerkaer's operator and a MAD: robust to edges in the
//                         region; texture still inflates it)
//   edge_width()          the 10-90 % rise across the mask's boundary: how sharp the silhouette
//                         is (the camera's PSF, anti-aliasing)
//   patch_features() and classify_patches()
//                         whether a classifier can tell patches of one image from the other's at
//                         all (AUC 0.5: it cannot), which catches differences none of the numbers
//                         above name
#pragma once

#include <cstddef>
#include <vector>

#include "core/expected.hpp"
#include "core/image.hpp"

namespace augrig::eval {

// The difference a - b over a region.
struct RegionDifference {
  std::size_t pixels = 0;  // masked pixels
  double mean_dn = 0;      // mean of a - b over every sample (NaN when no pixel is masked)
  double rms_dn = 0;       // root mean square of a - b (NaN when no pixel is masked)
};

// The mean and RMS of a - b over all channel samples of the pixels `mask` selects: the three
// colours of RGB8 and RGBA8 (alpha is not part of the look), the one sample of Mono8 and of a
// Bayer mosaic (compared site by site, undemosaiced, so that no interpolation enters the
// difference). Errors: a and b of different sizes or formats, a mask that is not Mono8 of their
// size.
Expected<RegionDifference> region_difference(ConstImageView a, ConstImageView b, ConstImageView mask);

// The noise's standard deviation (DN) in the region, estimated robustly: Immerkaer's (1996)
// Laplacian difference [1 -2 1; -2 4 -2; 1 -2 1] (which cancels every signal of the form
// f(x) + g(y): flat areas, ramps, horizontal and vertical edges; its response to white noise of
// sigma s has sigma 6 s) is applied per channel at every pixel whose whole 3x3 neighbourhood lies
// in the region; on a Bayer mosaic to each of its four site sub-images (neighbours 2 px apart, so
// that only samples of one colour filter are combined). All responses are pooled and the
// estimate is 1.4826 * median(|response|) / 6 (the median absolute deviation: a minority of
// responses on edges or specular spots moves it little). The responses of 8-bit images are
// integers; the median is interpolated within its integer bin, so that the estimate does not
// jump in steps of 0.25 DN.
//
// Includes the 8-bit rounding (1/12 DN^2 in the variance, 1 % at sigma 2; below about 0.5 DN the
// rounding dominates, and a region without any variation reads 0). Texture inflates the
// estimate: anything that the operator does not cancel reads as noise. Use it on smooth regions
// (the boom's interior) and on both images alike, so that any texture is shared.
// NaN when fewer than 50 responses. Errors: a mask that is not Mono8 of the image's size.
Expected<double> robust_noise_sigma(ConstImageView img, ConstImageView mask);

// The sharpness of the region's silhouette in an image.
struct EdgeWidth {
  int profiles = 0;           // profiles averaged
  double width_10_90_px = 0;  // distance between the 10 % and 90 % points (NaN with no profile)
};

// The mean 10-90 % rise distance of the image across the mask's boundary (issue 33 §3: the
// silhouette's sharpness, which the camera's PSF and the renderer's anti-aliasing set). Per
// boundary pixel (in the region, with a 4-neighbour out of it) on a smooth stretch of boundary:
//   - its outward normal from the gradient of the mask smoothed by a Gaussian (sigma 1.5 px);
//     skipped where that gradient is weak (thin parts, ends), where the normals of the boundary
//     pixels within 3 px differ from it by more than 20 degrees (corners, curves of radius below
//     about 12 px), or within 9 px of the image's border;
//   - the local boundary: a parabola fitted by weighted least squares to the midpoints of the
//     in/out pixel pairs around it (Gaussian weights of sigma 10 px, or 5 px where the long
//     window fails). The mask is decided at pixel centres, so the true boundary crosses each pair,
//     on average at its midpoint; the fit gives the boundary's sub-pixel position, its normal and
//     its curvature. Skipped where the midpoints lie off the parabola (RMS > 0.6 px) or its normal
//     leaves the smoothed mask's by more than 20 degrees;
//   - the luminance (Mono8 as is; RGB the mean of R, G and B; a Bayer mosaic averaged over 2 x 2
//     sites, which sees every colour filter once, so the mosaic does not read as an edge) of the
//     pixels within 1 px of the normal and 6 px of the boundary, each at its exact distance d from
//     the boundary. These samples take the place of bilinear samples along the normal, which
//     would add the interpolation's own blur (a projected tent: 1/6 px^2 of variance on average,
//     +13 % on the width of a sharp edge of s = 0.7 px) varying with the sub-pixel phase; the
//     exact distances of pixels along a slanted boundary fall at all phases instead (the
//     slanted-edge method of ISO 12233);
//   - normalised by the means of its plateaus (|d| >= 4.5 px), and skipped when those differ by
//     less than min_contrast_dn or when it is not roughly monotonic (a decrease of more than 30 %
//     of the contrast between 5-sample running means: another edge inside the window).
// The normalised samples of all profiles (each oriented to rise from 0 inside to 1 outside) are
// averaged in 0.25 px bins of d; the 10 % and 90 % crossings of that average (linearly
// interpolated, searched outwards from the 50 % crossing nearest the boundary) give the width.
//
// A Gaussian edge of sigma s gives 2.5631 s: on synthetic erf edges 3 degrees or more off a row,
// a column or a diagonal, within 0.05 px for s = 0.7 to 1.5 (tests/eval/look_compare_test.cpp).
// The width is the edge's as the pixels hold it (a sensor's pixel integration included); the
// Bayer 2 x 2 average adds 1/4 px^2 of variance. Compare widths measured alike (same format).
// Limits: boundaries within ~2.5 degrees of a row or column, or ~1.5 degrees of a diagonal, are
// placed by the mask only over long stretches (its staircase steps rarely), and their pixels'
// distances fall at few sub-pixel phases: up to +-0.2 px there. Noise averages out over the
// profiles but scatters the result: about 0.1 px for one 140 px edge at 10:1 contrast to noise;
// pool many profiles (frames) at low contrast.
// NaN width when no profile passes. Errors: a mask that is not Mono8 of the image's size.
Expected<EdgeWidth> edge_width(ConstImageView img, ConstImageView mask, double min_contrast_dn = 20);

// Number of values patch_features() returns, and their order.
inline constexpr int kPatchFeatureCount = 9;
// Statistics of one size x size patch of the image at (x0, y0), for telling two looks apart:
//   0    mean (DN)
//   1    variance (DN^2)
//   2    gradient energy: mean squared central differences (DN^2)
//   3    high-pass energy: variance of the 4-neighbour Laplacian (DN^2)
//   4..7 the mean-removed patch's 2-D DCT energy in radial frequency bands, as fractions of the
//        total: normalised radius sqrt(u^2 + v^2) / m of the m x m coefficients in (0, 1/4],
//        (1/4, 1/2], (1/2, 3/4], above (the shape of the spectrum: blur, noise colour); m is the
//        largest even size in the patch (cv::dct needs even sizes)
//   8    robust_noise_sigma() of the patch (DN), from its raw samples (Bayer: per site), from
//        however many responses it has (never NaN)
// 0-7 are taken on the luminance (as edge_width(): Mono8 as is, RGB the mean of R, G and B, a
// Bayer mosaic averaged over 2 x 2 sites, which gives (size - 1)^2 values). Empty when the patch
// does not lie in the image or size < 8.
std::vector<float> patch_features(ConstImageView img, int x0, int y0, int size);

// How well two classifiers tell feature vectors of a from those of b on a held-out test set.
struct ClassifierResult {
  double auc_random_trees = 0;      // AUC of cv::ml::RTrees on the test set
  double auc_logistic = 0;          // AUC of cv::ml::LogisticRegression on the test set
  std::size_t train = 0, test = 0;  // samples of both classes together
};

// Trains cv::ml::RTrees (200 trees, depth <= 10; score: the fraction of trees voting b) and
// cv::ml::LogisticRegression (features standardised by the training set's mean and standard
// deviation; score: its linear predictor, which orders samples as the predicted probability of b
// does without saturating in float) to tell a (label 0) from b (label 1) on the training sets,
// and scores each on the test sets by its AUC (auc()). 0.5: the two looks cannot be told apart by
// these features; 1: always. Deterministic: cv::theRNG() is reseeded before training (and left
// so). Errors: an empty set, vectors of differing lengths, a training failure inside OpenCV.
Expected<ClassifierResult> classify_patches(const std::vector<std::vector<float>>& train_a,
                                            const std::vector<std::vector<float>>& train_b,
                                            const std::vector<std::vector<float>>& test_a,
                                            const std::vector<std::vector<float>>& test_b);

// The area under the ROC curve of scores that should be higher for b than for a, by the
// Mann-Whitney U statistic: the fraction of (a, b) pairs with score_b > score_a, ties counting
// one half. 1: perfect separation, 0: perfectly reversed, 0.5: no separation. NaN when either
// set is empty.
double auc(const std::vector<double>& scores_a, const std::vector<double>& scores_b);

}  // namespace augrig::eval
