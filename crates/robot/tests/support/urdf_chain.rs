//! A long URDF for the reading tests and the URDF benchmark (`#[path]`-included, one
//! source).

/// A chain of `n` revolute joints `j0..`, links `l0..ln`.
pub fn chain_urdf(n: usize) -> String {
    let mut s = String::from("<robot name=\"long\">\n  <link name=\"l0\"/>\n");
    for i in 0..n {
        s.push_str(&format!(
            "  <joint name=\"j{i}\" type=\"revolute\">\n    <parent link=\"l{i}\"/>\n    <child link=\"l{}\"/>\n    <origin xyz=\"0 0 0.1\" rpy=\"0 0 0\"/>\n    <axis xyz=\"0 0 1\"/>\n    <limit lower=\"-1\" upper=\"1\" effort=\"10\" velocity=\"2\"/>\n  </joint>\n  <link name=\"l{}\">\n    <inertial>\n      <origin xyz=\"0.01 0 0\" rpy=\"0 0 0\"/>\n      <mass value=\"1.0\"/>\n      <inertia ixx=\"0.01\" ixy=\"0\" ixz=\"0\" iyy=\"0.01\" iyz=\"0\" izz=\"0.01\"/>\n    </inertial>\n  </link>\n",
            i + 1,
            i + 1
        ));
    }
    s.push_str("</robot>\n");
    s
}
