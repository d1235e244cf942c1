#pragma once
// A synthetic 1-D "tunnel" for the coarse tests: place i looks like one of a few tile
// textures chosen at random, so single frames alias (every tile type recurs every few places)
// while a sequence of ~10 places is unique. Between places the view cross-fades; queries add
// noise and an illumination change.

#include <mrpt/img/CImage.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace lookup::coarse::testing {

class SyntheticRoute {
  public:
    static constexpr int kW = 64;  ///< image width = one tile [px]
    static constexpr int kH = 48;

    SyntheticRoute(int places, int tile_types, unsigned seed) : rng_(seed) {
        cv::theRNG().state = seed;
        std::vector<cv::Mat> tiles;
        for (int k = 0; k < tile_types; ++k) {
            cv::Mat t(kH, kW, CV_32F);
            cv::randn(t, 0, 1);
            cv::GaussianBlur(t, t, cv::Size(0, 0), 2.5);
            cv::normalize(t, t, 40, 215, cv::NORM_MINMAX);
            tiles.push_back(t);
        }
        std::uniform_int_distribution<int> pick(0, tile_types - 1);
        for (int i = 0; i < places + 2; ++i) type_.push_back(pick(rng_));
        tiles_ = tiles;
    }

    int places() const { return static_cast<int>(type_.size()) - 2; }
    /// Places [from, to] all look alike (one tile type): a long uniform drive.
    void makeUniform(int from, int to, int type) {
        for (int i = from; i <= to; ++i) type_.at(i) = type;
    }
    int typeAt(int place) const { return type_.at(place); }

    /// Image at route position x in [0, places()] (tiles), grey, with additive Gaussian noise
    /// of `noise` grey levels and the illumination change g * I + b.
    mrpt::img::CImage image(double x, double noise, double gain = 1.0, double bias = 0.0) {
        // Appearance changes smoothly with position (as a forward camera approaching the
        // next stretch of tunnel): a cross-fade between the tiles of the two nearest places.
        const int first = std::max(0, std::min(static_cast<int>(std::floor(x)), places()));
        const double f = std::clamp(x - first, 0.0, 1.0);
        cv::Mat win = tiles_[type_[first]] * (1.0 - f) + tiles_[type_[first + 1]] * f;
        cv::Mat n(kH, kW, CV_32F);
        cv::theRNG().state = ++rng_seed_;
        cv::randn(n, 0, noise);
        win = win * gain + bias + n;
        cv::Mat out;
        win.convertTo(out, CV_8U);
        return mrpt::img::CImage(out, mrpt::img::DEEP_COPY);
    }

  private:
    std::mt19937 rng_;
    std::vector<int> type_;
    std::vector<cv::Mat> tiles_;
    std::uint64_t rng_seed_ = 12345;
};

}  // namespace lookup::coarse::testing
