#pragma once
// The reference side of the coarse stage: one descriptor per forward-camera image of a
// surveyed traverse, with its time stamp and (when surveyed) its pose. Built from a rawlog,
// or saved to / loaded from a file kept in the reference database folder.

#include <mrpt/poses/CPose3D.h>

#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lookup/coarse/descriptor.h"
#include "lookup/coarse/options.h"
#include "lookup/common/pose_files.h"

namespace lookup::coarse {

/// A descriptor file or sequence that cannot be used; the message names the file and reason.
class DescriptorFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// The reference sequence, in travel order. Descriptors all have the layout given at
/// construction; poses are either present for every frame or for none.
class ReferenceDescriptors {
  public:
    /// Layout from the thumbnail/patch fields of `options` (validated).
    explicit ReferenceDescriptors(const CoarseOptions& options);

    /// Appends a frame. Throws std::invalid_argument when the descriptor length is wrong, the
    /// time goes backwards, or poses are given for some frames and not others.
    void add(double time_s, Descriptor descriptor,
             const std::optional<mrpt::poses::CPose3D>& pose = std::nullopt);

    std::size_t size() const { return times_.size(); }
    bool empty() const { return times_.empty(); }
    double time(std::size_t i) const { return times_.at(i); }
    const Descriptor& descriptor(std::size_t i) const { return descriptors_.at(i); }
    bool hasPoses() const { return !poses_.empty() && poses_.size() == times_.size(); }
    /// Pose of frame i in the map frame; throws std::logic_error when there are no poses.
    const mrpt::poses::CPose3D& pose(std::size_t i) const;
    /// Distance travelled along the reference from frame 0 to frame i [m] (needs poses).
    double arcLength(std::size_t i) const;
    /// All arc lengths, index as arcLength() (for hot loops; throws as arcLength()).
    const std::vector<double>& arcLengths() const;
    /// Index of the frame nearest in time to `time_s` (references must not be empty).
    std::size_t nearestInTime(double time_s) const;
    /// Index of the frame whose position is nearest to `p` (needs poses).
    std::size_t nearestInSpace(const mrpt::poses::CPose3D& p) const;

    /// Size of the camera images the descriptors came from [px] (0 when unknown); queries of
    /// another size are refused because their thumbnails would be distorted differently.
    int imageWidth() const { return image_width_; }
    int imageHeight() const { return image_height_; }
    void setImageSize(int width, int height);

    /// The thumbnail/patch layout (only those fields of the returned options are meaningful).
    const CoarseOptions& layout() const { return layout_; }

    /// Versioned little-endian binary file ("LKCOARSE", version 1). Written to `<path>.tmp`
    /// and renamed. Throws DescriptorFileError naming the file.
    void saveDescriptors(const std::string& path) const;
    /// Throws DescriptorFileError naming the file for a missing, foreign, truncated or
    /// inconsistent file.
    static ReferenceDescriptors loadDescriptors(const std::string& path);

  private:
    CoarseOptions layout_;
    int image_width_ = 0;
    int image_height_ = 0;
    std::vector<double> times_;
    std::vector<Descriptor> descriptors_;
    std::vector<mrpt::poses::CPose3D> poses_;
    std::vector<double> arc_;
};

/// Reads every `options.camera_label` image of a rawlog into a reference sequence. With
/// `poses` (e.g. the survey's pose track), each frame gets the pose interpolated at its time
/// stamp; frames outside the track or in gaps longer than `max_gap_s` make it throw. Throws
/// common::RawlogError naming the file and record for an absent label (listing the labels
/// present), images of different sizes or unreadable data.
ReferenceDescriptors buildReferenceSequence(const std::string& rawlog_path,
                                            const CoarseOptions& options,
                                            const common::PoseTrack* poses = nullptr,
                                            double max_gap_s = 1.0);

}  // namespace lookup::coarse
