//! What every `.vtu` mochi writes begins with: the VTK XML header, the frame's time and step as
//! field data, and the opening of its one `<Piece>` of vertices.

/// The XML of a `.vtu` of `n` vertices at `time` and `step` up to its `<Piece>`'s first section.
pub(super) fn vtu_opening(time: f64, step: u64, n: usize) -> String {
    format!(
        r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <UnstructuredGrid>
    <FieldData>
      <DataArray type="Float64" Name="TimeValue" NumberOfTuples="1" format="ascii">{time}</DataArray>
      <DataArray type="UInt64" Name="step" NumberOfTuples="1" format="ascii">{step}</DataArray>
    </FieldData>
    <Piece NumberOfPoints="{n}" NumberOfCells="{n}">
"#
    )
}
