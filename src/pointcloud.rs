//! TEMPORARY STUB
use glam::DVec3;
pub struct PointCloud {
    pub positions: Vec<DVec3>,
    pub normals: Option<Vec<DVec3>>,
    pub colors: Option<Vec<[f32; 3]>>,
    pub radii: Option<Vec<f64>>,
}
pub fn read_ply(path: &std::path::Path) -> crate::error::Result<PointCloud> {
    Err(crate::error::Error::input(path, "x", "stub"))
}
pub fn estimate_normals(positions: &[DVec3], _k: usize) -> Vec<DVec3> {
    vec![DVec3::Z; positions.len()]
}
pub fn estimate_radii_and_areas(
    positions: &[DVec3],
    _n: &[DVec3],
    _k: usize,
) -> (Vec<f64>, Vec<f64>) {
    (vec![0.01; positions.len()], vec![1e-4; positions.len()])
}
