#pragma once
// fitAppearance's stages (appearance_fit.hpp), in the paper's order: the light from the specular highlights, the
// light and the diffuse reflectance on the specular-free image, the specular lobe on the frame, and the result with
// its metrics and status. Each stage reads what the ones before it left in the fitter.
#include "appearance_fit_model.hpp"

#include <chrono>
#include <string>
#include <vector>

namespace rehearse::imaging::detail {

class AppearanceFitter {
 public:
  AppearanceFitter(const cv::Mat3b& frame, const SurfaceGeometry& g, const AppearanceFitOptions& o)
      : in_{frame, g, o} {}

  // The organ's pixels that can be trusted (usablePixels); throws InputError when too few.
  void findUsablePixels();
  // Stage 1 (appearance_fit_light.cpp): the light's start from the specular highlights.
  void lightFromHighlights();
  // Stage 2 (appearance_fit_light.cpp): the light, the scope's fall-off and kd on the specular-free image, and
  // which parts of the model the frame bears out.
  void fitLightAndDiffuse();
  // Stage 3 (appearance_fit_specular.cpp): ks and the roughness on the frame, the light and kd refined with them.
  void fitSpecular();
  // The result (appearance_fit_metrics.cpp): Theta as delivered, the shares it explains and the status.
  void fillUnmeasuredKs();
  void deliverTheta();
  void measureShares();
  // The light the frame shows (appearance_fit_room.cpp): a distant light and an ambient term beside the scope's, kept
  // where the frame bears them out.
  void fitSecondSource();
  void writeStatus();
  AppearanceFitResult finish();

 private:
  using Clock = std::chrono::steady_clock;
  static Clock::time_point tick() { return Clock::now(); }
  static double ms(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
  }
  void report(double share, const std::string& what) const {
    if (in_.o.progress && !in_.o.progress(share, what)) throw AppearanceCancelled();
  }

  // Stage 2's parts.
  std::vector<Sample> samplesAwayFromHighlights();
  void lightFromStarts();
  void checkModelParts();
  // The share a light explains: kd projected on the kept diffuse samples, the residual over all of them.
  double shareOf(const Light& l, const Parts& parts) const;
  // Stage 3's parts.
  std::vector<Sample> specularSamples(const cv::Mat1b& clean) const;
  void roughnessOnGrid(const std::vector<Sample>& specSamples);
  void refineWithHighlights(const std::vector<Sample>& specSamples);
  void specularOverShadingKd(const std::vector<Sample>& specSamples);
  void censoredKs(const std::vector<Sample>& specSamples, int c);

  struct Input {
    const cv::Mat3b& frame;
    const SurfaceGeometry& g;
    const AppearanceFitOptions& o;
  };
  // The diffuse stage's samples of the specular-free image: all of them (the shares are over these, outliers
  // included) and those kept after trimming (which the fits use).
  struct DiffuseSamples {
    std::vector<Sample> kept, all;
  };
  // The estimate as the stages refine it.
  struct Estimate {
    Eigen::Vector3d highlightLight = Eigen::Vector3d::Zero();  ///< stage 1's light
    Light lit;
    double sigma = 0.1;  ///< the roughness
    Projected lin;       ///< kd and ks
    bool settled = false;
  };

  Input in_;
  AppearanceFitResult res_;
  DiffuseSamples diffuse_;
  Estimate est_;
  std::string unmeasured_;  ///< the channels whose ks is not in the frame ("red and blue")
};

}  // namespace rehearse::imaging::detail
