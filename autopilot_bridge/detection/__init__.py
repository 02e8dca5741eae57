"""From a camera frame to what the policy sees: the detector, the view I, and which blobs are
targets already found."""
