function dy = rigid(t,y)
% RIGID  Euler's equations of a rigid body without external forces (Lab 5)
dy = zeros(3,1);    % a column vector
dy(1) = y(2) * y(3);
dy(2) = -y(1) * y(3);
dy(3) = -0.51 * y(1) * y(2);
