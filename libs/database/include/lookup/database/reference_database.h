#pragma once
// Read access to a reference database folder written by lookup-survey (DatabaseWriter):
// reference metadata in memory, KD-trees (nanoflann) over reference vehicle and ceiling camera
// positions, a time index, and images read lazily through a bounded LRU cache.

#include <mrpt/math/TPoint2D.h>
#include <mrpt/poses/CPose3D.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "lookup/database/reference.h"

namespace lookup::database {

/// A (distance, reference index) pair returned by the queries; distance in m or s.
struct Neighbour {
    std::size_t index = 0;
    double distance = 0;
};

class ReferenceDatabase {
  public:
    /// Loads db.ini and refs.rawlog from `dir`. `image_cache_capacity`: the most images kept in
    /// memory at once. Throws DatabaseError naming the file (and record) on a missing or corrupt
    /// database or a missing image file.
    static ReferenceDatabase load(const std::string& dir, std::size_t image_cache_capacity = 64);

    ReferenceDatabase(ReferenceDatabase&&) noexcept;
    ReferenceDatabase& operator=(ReferenceDatabase&&) noexcept;
    ~ReferenceDatabase();

    const std::string& directory() const;
    const DatabaseInfo& info() const;
    std::size_t size() const;
    const Reference& reference(std::size_t i) const;
    const std::vector<Reference>& references() const;

    // The spatial queries (nearest, nearestCameras, withinRadius) return current references
    // only: a superseded one saw a ceiling that has since changed. nearestInTime returns any,
    // since the coarse stage's key is a time on the survey's own time line.

    /// The `k` references whose vehicle positions are nearest to `position` (map frame, m),
    /// nearest first (fewer if the database is smaller).
    std::vector<Neighbour> nearest(const mrpt::math::TPoint2D& position, std::size_t k) const;
    std::vector<Neighbour> nearest(const mrpt::poses::CPose3D& pose, std::size_t k) const;
    /// The `k` references whose ceiling cameras are nearest to `camera_position` (map frame, m),
    /// nearest first: the references that saw most of the ceiling a camera there sees, whatever
    /// the vehicle's heading and camera mount.
    std::vector<Neighbour> nearestCameras(const mrpt::math::TPoint2D& camera_position,
                                          std::size_t k) const;
    /// All references whose vehicle positions lie within `radius_m` of `position`, nearest
    /// first.
    std::vector<Neighbour> withinRadius(const mrpt::math::TPoint2D& position,
                                        double radius_m) const;
    /// The `k` references whose ceiling time stamps are nearest to `time_s`, nearest first
    /// (superseded ones included).
    std::vector<Neighbour> nearestInTime(double time_s, std::size_t k) const;

    /// Adds references held in memory only (the localiser's online refresh: nothing is written
    /// to the folder), each with its 8-bit grey ceiling image, ids set to their indices, and
    /// marks the references `superseded` as superseded by `by`. The spatial queries see the
    /// change at once. Invalidates references to Reference objects obtained before.
    void addInMemory(std::vector<std::pair<Reference, cv::Mat>> added,
                     const std::vector<std::size_t>& superseded, const std::string& by);
    /// References added by addInMemory.
    std::size_t inMemoryCount() const;

    /// Reference indices with a forward image, in increasing forward-image time: the sequence
    /// the coarse stage builds its descriptors from.
    const std::vector<std::size_t>& forwardSequence() const;

    /// Images (8-bit grey), read lazily through the bounded cache.
    cv::Mat ceilingImage(std::size_t i) const;
    cv::Mat forwardImage(std::size_t i) const;  ///< empty Mat if the reference has none
    std::size_t imagesInMemory() const;         ///< images currently cached
    std::size_t imageDiskReads() const;         ///< images read from disk so far
    std::size_t imageCacheCapacity() const;

  private:
    struct Impl;
    explicit ReferenceDatabase(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace lookup::database
