//! Command-line options that choose the modelled chain of a URDF tree, shared by every
//! command that takes `--robot`.
use anyhow::{Context, bail};
use robot::{ChainSelection, LoadedRobot, Robot, RobotSource, UrdfFriction};

/// `--base-link`, `--tip-link`, `--side-joint`.
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct ChainArgs {
    /// URDF: first link of the modelled chain (its frame is the base frame); default: the
    /// root link.
    #[arg(long, value_name = "LINK")]
    pub base_link: Option<String>,
    /// URDF: last link of the modelled chain; default: the single link that ends a path of
    /// moving joints below the base (an error lists the candidates when there are several,
    /// e.g. a gripper's fingers). Branches off the chain ride on it as fixed bodies.
    #[arg(long, value_name = "LINK")]
    pub tip_link: Option<String>,
    /// URDF: position of a moving joint outside the chain, `NAME=Q` (rad, or m for a
    /// prismatic joint), comma separated (e.g. `finger_joint1=0.02,finger_joint2=0.02`);
    /// the others are held at 0.
    #[arg(
        long,
        value_name = "NAME=Q",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub side_joint: Vec<String>,
    /// URDF: take each joint's `<dynamics damping friction>` as its nominal viscous
    /// [N·m·s/rad] and Coulomb [N·m] friction; default: left out, as Pinocchio's RNEA does.
    #[arg(long)]
    pub urdf_friction: bool,
}

impl ChainArgs {
    /// The selection these options describe.
    pub fn selection(&self) -> anyhow::Result<ChainSelection> {
        let mut side_joint_positions = Vec::with_capacity(self.side_joint.len());
        for spec in &self.side_joint {
            let (name, q) = spec
                .split_once('=')
                .with_context(|| format!("--side-joint '{spec}': expected NAME=Q"))?;
            let q: f64 = q
                .trim()
                .parse()
                .with_context(|| format!("--side-joint '{spec}': position"))?;
            if !q.is_finite() {
                bail!("--side-joint '{spec}': the position must be finite");
            }
            side_joint_positions.push((name.trim().to_string(), q));
        }
        Ok(ChainSelection {
            base_link: self.base_link.clone(),
            tip_link: self.tip_link.clone(),
            side_joint_positions,
            urdf_friction: if self.urdf_friction {
                UrdfFriction::Nominal
            } else {
                UrdfFriction::LeftOut
            },
        })
    }

    /// Loads the robot's chain and prints the folded joints' warning to stderr.
    pub fn load_and_warn(&self, source: &RobotSource) -> anyhow::Result<Robot> {
        Ok(warn(source.load_chain(&self.selection()?)?))
    }
}

/// The robot of `loaded`, after printing the warning that names the moving joints folded
/// out of its chain (if any) to stderr.
pub fn warn(loaded: LoadedRobot) -> Robot {
    if let Some(w) = loaded.warning() {
        eprintln!("warning: {w}");
    }
    loaded.robot
}
