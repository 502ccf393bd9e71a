//! tridem DEM
